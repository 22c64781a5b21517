"""Run the test suite on a busy machine, as `make test-under-load` does.

    python tests/under_load.py [--runs 3] [--hogs N] [-- PYTEST ARGS]

Beside each run of the suite (pytest with the arguments after ``--``: ``make
test-under-load`` gives it ``make test``'s), ``--hogs`` CPU
hogs (default: one per core) spin at the suite's own priority, so every test
process gets a fraction of a core, as on a laptop that also builds or plans,
or a CI machine shared with other jobs. A hog is a plain Python busy loop: no
package to install. Runs stop at the first failing one; the exit status is
that run's. Each run's verdict and wall time are printed at the end.
"""

import argparse
import multiprocessing
import os
import subprocess
import sys
import time

PYTEST = [sys.executable, "-m", "pytest"]


def _spin() -> None:
    while True:
        pass


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3, help="consecutive runs of the suite")
    parser.add_argument("--hogs", type=int, default=os.cpu_count() or 1,
                        help="busy processes beside the suite")
    parser.add_argument("pytest_args", nargs="*", help="pytest's arguments (after --)")
    args = parser.parse_args(argv)
    results = []
    for run in range(1, args.runs + 1):
        hogs = [multiprocessing.Process(target=_spin, daemon=True) for _ in range(args.hogs)]
        for hog in hogs:
            hog.start()
        print(f"under load: run {run} of {args.runs} beside {args.hogs} CPU hog(s)", flush=True)
        start = time.monotonic()
        try:
            status = subprocess.call(PYTEST + args.pytest_args)
        finally:
            for hog in hogs:
                hog.terminate()
        results.append((run, status, time.monotonic() - start))
        if status:
            break
    for run, status, seconds in results:
        verdict = "passed" if status == 0 else f"FAILED (exit {status})"
        print(f"under load: run {run}: {verdict} in {seconds / 60:.1f} min", flush=True)
    return results[-1][1]


if __name__ == "__main__":
    sys.exit(main())
