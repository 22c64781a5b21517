"""Progress display for long work: one rich progress bar per pipeline stage."""

import contextlib
import sys

from rich.console import Console
from rich.progress import (
    BarColumn,
    Progress,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)

console = Console(stderr=True, soft_wrap=True)  # long paths stay on one line in logs

STAGE_TEXT = {
    "terrain": "loading terrain",
    "exposure": "exposure surface",
    "viewpoints": "candidate viewpoints",
    "visibility": "visibility sets",
    "travel graph": "hidden travel graph",
    "travel times": "hidden travel times between viewpoints",
    "candidate bases": "candidate bases: quick bounds",
    "launch checks": "candidate bases: proving their takeoffs",
    "allocation": "allocating viewpoints",
    "lower bound": "lower bound: how far from optimal",
    "routes": "hidden routes",
    "write": "writing files",
}


def note_first_compile() -> None:
    """Say why the first plan after an install is slow (numba compiling), once per
    version of the kernels' sources (`planner._kernel_cache_dir`)."""
    import planner

    if not planner.kernels_compiled():
        console.print("first plan with this version of the planner: numba compiles its "
                      "kernels (1.5-3 min on 2 cores, once; make install does it ahead)",
                      markup=False)


@contextlib.contextmanager
def stage_progress(enabled=None):
    """Yield ``progress(stage, fraction)``; draws bars on a terminal, quiet lines otherwise."""
    if enabled is None:
        enabled = True
    if not enabled:
        yield lambda stage, fraction: None
        return
    bars = Progress(TextColumn("{task.description:<24}"), BarColumn(), TextColumn(
        "{task.percentage:>3.0f}%"), TimeElapsedColumn(), TextColumn("left"),
        TimeRemainingColumn(), console=console,
        transient=False, disable=not console.is_terminal)
    tasks = {}

    def progress(stage, fraction):
        if stage not in tasks:
            tasks[stage] = bars.add_task(STAGE_TEXT.get(stage, stage), total=1.0)
            if not console.is_terminal:
                print(f"... {STAGE_TEXT.get(stage, stage)}", file=sys.stderr, flush=True)
        bars.update(tasks[stage], completed=min(max(fraction, 0.0), 1.0))

    with bars:
        yield progress
