"""What ``--max-silence`` keeps of the radio link, and what it costs the plan.

    .venv/bin/python -m benchmarks silence [--quick]

On the demo's plan (`gcs/data/demo.toml`) and four seeded synthetic terrains (160 x
160 cells of 30 m, 3 UAVs from one base near a corner, one outpost at the centre,
an antenna on a 2 m mast at the base), each planned without a limit and with
``--max-silence`` 60 and 180 s (RT, deterministic: the same routes before the
check-ins, so the limit's cost is the check-ins' alone): the share of the fleet's
airborne time out of contact, the longest silence, the check-ins made, whether the
limit was kept and by how much not, the floor (the least longest silence any route
through the same viewpoints can have: from contact to the farthest and back), the
coverage time and what the check-ins added to it (read in the same plan, before and
after them), and the check-ins' stage time.
``--quick``: the demo and one synthetic terrain, the 60 s limit only.
"""

import sys
import time
import warnings
from dataclasses import replace
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.cases import synthetic_case  # noqa: E402
from planner.pipeline import plan_mission  # noqa: E402
from planner.scenario import make_scenario, read_scenario  # noqa: E402

DEMO = Path(__file__).resolve().parents[1] / "gcs" / "data" / "demo.toml"
SYNTHETIC = (("hills", 3), ("ridges", 7), ("peaks", 5), ("mixed", 1))
SIDE = 160
LIMITS = (None, 60.0, 180.0)


def _demo():
    return replace(make_scenario(read_scenario(DEMO), {}), method="rt"), None, None


def _row(name, limit, plan, seconds) -> str:
    m = plan.metrics
    link = m["link"]
    kept = link.get("max_silence")
    if kept is None:
        said = f"{'-':>6} {'-':>5} {'-':>16} {'-':>8} {'-':>8}"
    else:
        over = max(kept["over_s"], default=0.0)
        said = (f"{sum(kept['check_ins']):>6} {'yes' if kept['met'] else 'no':>5} "
                f"{over:>14.0f} s {max(kept['floor_s'], default=0.0):>6.0f} s "
                f"{kept['coverage_time_added_s'] / 60:>+6.1f} m")
    return (f"{name:<18} {'-' if limit is None else f'{limit:.0f} s':>6} "
            f"{100 * link['share']:>6.1f} % {link['longest_s']:>8.0f} s {said} "
            f"{m['coverage_time_s'] / 60:>8.1f} m {plan.timing_s.get('check-ins', 0.0):>7.1f} s"
            f" {seconds:>6.0f} s")


def main(argv=None):
    quick = "--quick" in (sys.argv[1:] if argv is None else argv)
    cases = [("demo (RT)", _demo)] + [(f"{f} seed {s}",
                                       lambda f=f, s=s: synthetic_case(f, s, SIDE, "rt"))
                                      for f, s in SYNTHETIC[:1 if quick else None]]
    head = (f"{'case':<18} {'limit':>6} {'silent':>8} {'longest':>10} {'checks':>6} "
            f"{'kept':>5} {'longest over':>16} {'floor':>8} {'cost':>8} {'coverage':>10} "
            f"{'stage':>9} {'plan':>8}")
    print(head)
    print("-" * len(head))
    for name, make in cases:
        scenario, terrain, outposts = make()
        for limit in LIMITS[:2] if quick else LIMITS:
            start = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                _, outcome = plan_mission(replace(scenario, max_silence_s=limit),
                                          terrain=terrain, outposts=outposts, scheduler=None)
            print(_row(name, limit, outcome.plan, time.perf_counter() - start), flush=True)


if __name__ == "__main__":
    main()
