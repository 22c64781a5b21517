"""The plan folder `gcs plan` writes: every file staged, then moved into place.

What it holds: ``plan.json``, the planning context (`planner.context`: the
terrain, lowest seen altitudes, viewpoints, visibility sets, travel graph),
``exposure.tif`` and ``coverage.tif``, the two plots, and the mission files
per vehicle (each mission proven hidden and clear before anything is moved),
GeoJSON and KML.
"""

import os
import shutil
import tempfile
from pathlib import Path

import numpy as np

from planner import plan as plan_files
from planner.terrain import write_grid, write_terrain

VOIDS_FILE = "voids.tif"


def void_grid(terrain):
    """uint8 grid of the DEM's voids (1 filled by interpolation, 2 no data), None
    when it has none."""
    filled = terrain.meta.get("filled_mask")
    missing = ~terrain.valid
    if filled is None and not missing.any():
        return None
    grid = np.zeros(terrain.shape, np.uint8)
    if filled is not None:
        grid[filled] = 1
    grid[missing] = 2
    return grid


def coverage_grid(ctx, counts) -> np.ndarray:
    """int16 grid: distinct UAVs seeing each target cell, -1 outside S_c."""
    grid = np.full(ctx.terrain.shape, -1, np.int16)
    grid.flat[ctx.visibility.target_cells] = np.minimum(counts, np.iinfo(np.int16).max)
    return grid


def write_plan_folder(directory, ctx, outcome) -> list:
    """Write every output into a staging folder, then move each into place.

    Mission files are built (and their legs checked) before anything is moved,
    so a refused plan leaves the directory as it was.
    """
    from gcs.plots import overview_png, view3d_png
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
        voids = void_grid(ctx.terrain)
        if voids is not None:
            grids.append((VOIDS_FILE, voids, None, "DEM voids: 1 = filled by interpolation "
                          "(terrain lowered and clearance raised there), 2 = no data"))
        for name, grid, nodata, what in grids:
            write_grid(staging / name, grid, ctx.terrain, nodata=nodata)
            written.append((staging / name, what))
        written += ctx.save(staging)
        overview_png(staging / "overview.png", ctx.terrain, ctx.surface, outcome.plan,
                     ctx.unseen)
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
