"""`gcs exposure`: the exposure surface E of a DEM and its outposts, as a GeoTIFF.

The same scenario flags (and TOML file) as `gcs plan`, and the same first
stages (`planner.pipeline.exposure_stages`): the terrain, the outposts, E.
"""

from common.errors import InputError
from gcs.cli.options import add_scenario_arguments, scenario_from_args

HELP = "compute where UAVs fly hidden from the outposts (exposure surface E, GeoTIFF)"


def add_arguments(parser) -> None:
    add_scenario_arguments(parser, groups=("terrain and outposts", "hidden volume"))
    parser.add_argument("-o", "--output", metavar="EXPOSURE.TIF", required=True,
                        help="output GeoTIFF: E in metres AMSL (float32), NaN where not flyable")


def run(args) -> int:
    scenario = scenario_from_args(args)   # option errors before any heavy import
    if not scenario.sample and not scenario.outposts:
        raise InputError("--outposts", "no outposts file given (GeoJSON Points)")
    import numpy as np
    from rich.console import Console

    from gcs.progress import stage_progress
    from planner.pipeline import exposure_stages
    from planner.terrain import write_grid

    timing = {}
    with stage_progress() as progress:
        surface = exposure_stages(scenario, progress, timing)
        progress("write", 0.0)
        write_grid(args.output, surface.exposure.astype(np.float32), surface.terrain)
        progress("write", 1.0)
    Console().print(_summary(args.output, surface, timing))  # the result, on stdout
    return 0


def _summary(output, surface, timing):
    import numpy as np
    from rich.table import Table

    terrain, outposts = surface.terrain, surface.outposts
    cell_km2 = terrain.cell_size**2 / 1e6
    n_regions = int(surface.regions.max())
    sizes = np.bincount(surface.regions.ravel())[1:] if n_regions else np.zeros(1, int)
    valid = terrain.valid
    rows, cols = terrain.shape
    table = Table(title=f"exposure surface -> {output}", show_header=False, title_justify="left")
    table.add_column(style="bold")
    table.add_column()
    table.add_row("terrain", f"{terrain.source}")
    table.add_row("grid", f"{rows} x {cols} cells of {terrain.cell_size:.1f} m, {terrain.crs}, "
                          f"{valid.sum() * cell_km2:.1f} km2 with data")
    filled = terrain.meta.get("filled_voids", 0)
    if filled or terrain.meta.get("unfilled_voids"):
        table.add_row("voids", f"{filled} filled, {terrain.meta.get('unfilled_voids', 0)} "
                               "left unflyable")
    ranges = ", ".join("unlimited" if not np.isfinite(o.range_m) else f"{o.range_m / 1000:g} km"
                       for o in outposts)
    table.add_row("outposts", f"{len(outposts)} (ranges: {ranges})")
    flyable = int(surface.flyable.sum())
    table.add_row("flyable", f"{flyable * cell_km2:.1f} km2 "
                             f"({100 * flyable / max(valid.sum(), 1):.1f} % of the terrain)")
    table.add_row("regions", f"{n_regions}, largest {sizes.max() * cell_km2:.1f} km2")
    table.add_row("time", ", ".join(f"{k} {v:.2f} s" for k, v in timing.items()))
    return table
