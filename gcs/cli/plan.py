"""`gcs plan`: DEM and outposts in, hidden reduced-time coverage routes and mission files out."""

import os
import shutil
import tempfile
from pathlib import Path

import numpy as np
from rich.table import Table

from gcs.cli.options import add_scenario_arguments, scenario_from_args
from gcs.plots import overview_png, view3d_png
from gcs.progress import console, stage_progress
from planner.errors import InputError
from planner import plan as plan_files
from planner.geotiff import write_grid, write_terrain
from planner.pipeline import plan_mission

HELP = "plan hidden coverage routes for a UAV fleet and write the mission files"


def add_arguments(parser) -> None:
    add_scenario_arguments(parser)
    parser.add_argument("-o", "--output", required=True, metavar="DIR",
                        help="output directory (created; files in it are replaced atomically)")


def run(args) -> int:
    scenario = scenario_from_args(args)
    check_output_dir(args.output)
    with stage_progress() as progress:
        ctx, outcome = plan_mission(scenario, progress)
        progress("write", 0.0)
        written = write_outputs(args.output, ctx, outcome)
        progress("write", 1.0)
    print_summary(outcome.plan)
    for path, what in written:
        console.print(f"  {path}  [dim]{what}[/dim]")
    return 0


def coverage_grid(ctx, counts) -> np.ndarray:
    """int16 grid: distinct UAVs seeing each target cell, -1 outside S_c."""
    grid = np.full(ctx.terrain.shape, -1, np.int16)
    grid.flat[ctx.visibility.target_cells] = np.minimum(counts, np.iinfo(np.int16).max)
    return grid


def check_output_dir(directory) -> None:
    """Refuse an output folder that cannot be one before any work is done."""
    path = Path(directory)
    if path.exists() and not path.is_dir():
        raise InputError("-o", f"{path} is a file, not a folder")
    parent = next((p for p in [path, *path.parents] if p.exists()), Path("."))
    if not os.access(parent, os.W_OK | os.X_OK):
        raise InputError("-o", f"{path}: cannot write in {parent}")


def write_outputs(directory, ctx, outcome) -> list:
    """Write every output into a staging folder, then move each into place.

    Mission files are built (and their legs checked) before anything is moved,
    so a refused plan leaves the directory as it was.
    """
    from missions.export import export_plan_dir

    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=".gcs-plan-", dir=directory))
    try:
        outcome.plan.save(staging)
        write_terrain(staging / plan_files.TERRAIN_FILE, ctx.terrain)
        grids = [
            (plan_files.EXPOSURE_FILE, ctx.surface.exposure.astype(np.float32), None,
             "exposure surface E, metres AMSL, NaN where not flyable"),
            (plan_files.COVERAGE_FILE, coverage_grid(ctx, outcome.counts), -1,
             "distinct UAVs seeing each target cell, -1 = not a target"),
        ]
        written = [(staging / plan_files.PLAN_FILE, "the plan: routes, times, metrics"),
                   (staging / plan_files.TERRAIN_FILE, "working-grid DEM, metres AMSL: "
                    "band 1 for line of sight, band 2 for clearance")]
        for name, grid, nodata, what in grids:
            write_grid(staging / name, grid, ctx.terrain, nodata=nodata)
            written.append((staging / name, what))
        overview_png(staging / "overview.png", ctx.terrain, ctx.surface, outcome.plan)
        written.append((staging / "overview.png", "map of the hidden ceiling, outposts and routes"))
        view3d_png(staging / "view3d.png", ctx.terrain, ctx.surface, outcome.plan)
        written.append((staging / "view3d.png", "3-D view: terrain, hidden ceiling, routes"))
        written += export_plan_dir(staging, outcome.plan, firmware=ctx.scenario.firmware,
                                   surface=ctx.surface)
        moved = []
        for path, what in written:
            target = directory / Path(path).name
            os.replace(path, target)
            moved.append((target, what))
        _remove_stale_vehicle_files(directory, {target.name for target, _ in moved})
        return moved
    finally:
        shutil.rmtree(staging, ignore_errors=True)


def _remove_stale_vehicle_files(directory, kept) -> None:
    """A plan with fewer vehicles than the one it replaces: the old vehicles' mission
    files go, so nothing in the folder belongs to another plan."""
    for path in directory.glob("vehicle-*.*"):
        if path.name not in kept and path.suffix in (".plan", ".waypoints"):
            path.unlink()


def print_summary(plan) -> None:
    m = plan.metrics
    table = Table(title=f"{plan.method.upper()} plan, k = {m['k']}")
    for col in ("UAV", "snapshots", "coverage time", "mission time", "path"):
        table.add_column(col, justify="right")
    for v in plan.vehicles:
        table.add_row(str(v.id), str(len(v.snapshots)), _minutes(v.coverage_time_s),
                      _minutes(v.mission_time_s), f"{v.path_length_m / 1000:.1f} km")
    console.print(table)
    ratio = m.get("ratio_to_lower_bound")
    console.print(
        f"coverage time {_minutes(m['coverage_time_s'])} (lower bound "
        f"{_minutes(m['lower_bound_s'])}, ratio {ratio:.2f})" if ratio else
        f"coverage time {_minutes(m['coverage_time_s'])}")
    console.print(f"targets {m['targets']}: {m['k_covered']} seen by k+1 = {m['k'] + 1} "
                  f"UAVs ({100 * m['k_covered'] / max(m['targets'], 1):.1f} %); "
                  f"planned in {plan.timing_s.get('total', 0):.1f} s")


def _minutes(seconds) -> str:
    return f"{seconds / 60:.1f} min"
