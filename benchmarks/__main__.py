"""Run every benchmarks/bench_*.py module's main() in turn, printing their tables.

    .venv/bin/python -m benchmarks            # all of them
    .venv/bin/python -m benchmarks exposure   # only bench_exposure
    .venv/bin/python -m benchmarks plan --quick  # options go to every benchmark run;
                                                # each takes those it knows
"""

import importlib
import sys
import time
from pathlib import Path


def main(argv=None) -> int:
    args = sys.argv[1:] if argv is None else argv
    options = [a for a in args if a.startswith("-")]
    wanted = {a for a in args if not a.startswith("-")}
    names = sorted(p.stem for p in Path(__file__).parent.glob("bench_*.py"))
    for name in names:
        if wanted and name.removeprefix("bench_") not in wanted and name not in wanted:
            continue
        print(f"\n######## {name} ########", flush=True)
        start = time.perf_counter()
        importlib.import_module(f"benchmarks.{name}").main(options)
        print(f"({name}: {time.perf_counter() - start:.0f} s)", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
