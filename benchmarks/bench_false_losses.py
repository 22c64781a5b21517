"""False losses in simulated flights through radio shadows: before and after the plan's
predicted silences (issue 59).

    .venv/bin/python -m benchmarks false_losses [--quick]

A plan is flown on the built-in simulator with its radio (each link cut while the
terrain hides the vehicle from the plan's antenna), no fault: every loss declared
is a false one. Each flight is flown twice from the same plan folder:

- *before*: plan.json's predicted silences removed, as `gcs fly` knew nothing of
  them: every silence longer than --lost-after (5 s) reads as a shoot-down (until
  the first re-plan: the survivors' new routes carry the planner's silences);
- *after*: the plan as written, `gcs fly` expecting its silences.

Printed per flight: the vehicles declared lost (false losses), the re-plans, the
silences the monitor matched to a plan's, whether the required coverage was
reached, and how each vehicle ended by the simulator's own record (landed,
crashed, or still in the air when the flight ended). Plans: the tests' shared
synthetic plan (3 UAVs, RT) and the demo's (`gcs/data/demo.toml`, 4 UAVs, k = 1;
not with ``--quick``), ``RUNS`` flights each way.
"""

import json
import shutil
import sys
import tempfile
import time
import warnings
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from gcs.flight import Flight, FlyOptions  # noqa: E402
from gcs.plan_folder import write_plan_folder  # noqa: E402
from gcs.sim import (  # noqa: E402
    fleet_for_plan,
    free_base_port,
    radio_for_plan,
    read_track,
    terrain_ground,
    track_path,
)
from planner.pipeline import plan_mission  # noqa: E402
from planner.plan import PLAN_FILE, Plan  # noqa: E402
from planner.scenario import make_scenario, read_scenario  # noqa: E402

DEMO = Path(__file__).resolve().parents[1] / "gcs" / "data" / "demo.toml"
RUNS = 2
SPEEDUP = {"shared": 20.0, "demo": 50.0}


def _plans(folder, quick):
    """[(name, plan folder, terrain)]."""
    from conftest import _small_plan

    cases = [("shared", *_small_plan())]
    if not quick:
        cases.append(("demo", make_scenario(read_scenario(DEMO), {}), None, None))
    out = []
    for name, scenario, terrain, outposts in cases:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ctx, outcome = plan_mission(scenario, terrain=terrain, outposts=outposts,
                                        scheduler=None)
        d = Path(folder) / name
        write_plan_folder(d, ctx, outcome)
        out.append((name, d, ctx.terrain))
    return out


def _without_silences(plan_dir, folder) -> Path:
    """A copy of the plan folder whose plan.json predicts no silence."""
    d = Path(folder) / (plan_dir.name + "-before")
    shutil.copytree(plan_dir, d)
    data = json.loads((d / PLAN_FILE).read_text())
    for v in data["vehicles"]:
        v["silences"] = []
    (d / PLAN_FILE).write_text(json.dumps(data))
    return d


def _fly(plan_dir, terrain, speedup, out) -> tuple:
    """(the flight's report, {sysid: how the simulator's own record ends it})."""
    plan = Plan.load(plan_dir)
    fleet = fleet_for_plan(plan, speedup=speedup, base_port=free_base_port(10, len(plan.vehicles)),
                           terrain=terrain_ground(terrain), radio=radio_for_plan(plan, terrain),
                           track_dir=out / "tracks")
    flight = Flight(plan_dir, fleet.urls(), FlyOptions(output=out, plot=False,
                                                       set_failsafes=True))
    try:
        report = flight.run()
    finally:
        fleet.stop()
    ended = {}
    for v in plan.vehicles:
        events = [e["event"] for e in read_track(track_path(out / "tracks", v.id)).events]
        ended[v.id] = next((e for e in reversed(events) if e in ("landed", "crashed")),
                           "in the air")
    return report, ended


def main(argv=None):
    quick = "--quick" in (sys.argv[1:] if argv is None else argv)
    head = (f"{'plan':<7} {'monitor':<7} {'run':>3} | {'false losses':<14} {'re-plans':>8} "
            f"{'as planned':>10} {'coverage':>8} | {'ended':<28} {'wall':>6}")
    print(head)
    print("-" * len(head))
    with tempfile.TemporaryDirectory() as folder:
        for name, plan_dir, terrain in _plans(folder, quick):
            before = _without_silences(plan_dir, folder)
            for label, d in (("before", before), ("after", plan_dir)):
                for run in range(1, RUNS + 1):
                    start = time.perf_counter()
                    report, flown = _fly(d, terrain, SPEEDUP[name],
                                         Path(folder) / f"f-{label}{run}")
                    lost = [x["sysid"] for x in report["losses"]]
                    told = sum(len(v.get("out_of_contact", [])) for v in report["vehicles"])
                    ended = ", ".join(f"{s} {e}" for s, e in flown.items())
                    print(f"{name:<7} {label:<7} {run:>3} | {str(lost or '-'):<14} "
                          f"{len(report['replans']):>8} {told:>10} "
                          f"{'yes' if report['outcome']['coverage_reached'] else 'no':>8} | "
                          f"{ended:<28} {time.perf_counter() - start:>5.0f}s", flush=True)


if __name__ == "__main__":
    main()
