"""`gcs exposure`: the exposure surface E of a DEM and its outposts, as a GeoTIFF."""

import argparse
import time
import warnings
from contextlib import contextmanager

import numpy as np
from rich.console import Console
from rich.progress import BarColumn, Progress, SpinnerColumn, TextColumn, TimeElapsedColumn
from rich.table import Table

from planner.dem import load_dem, sample_terrain
from planner.errors import InputError
from planner.exposure import ExposureParams, compute_exposure
from planner.geotiff import write_grid
from planner.outposts import load_outposts, sample_outposts

HELP = "compute where UAVs fly hidden from the outposts (exposure surface E, GeoTIFF)"

_DEFAULTS = ExposureParams()


def add_arguments(parser) -> None:
    src = parser.add_argument_group("terrain and outposts")
    src.add_argument("--dem", nargs="+", metavar="DEM", default=argparse.SUPPRESS,
                     help="DEM files: GeoTIFF (any CRS) or SRTM .hgt tiles; several are "
                          "mosaicked")
    src.add_argument("--sample", action="store_true", default=argparse.SUPPRESS,
                     help="use the built-in terrain (USGS Jacksboro DEM) and outposts")
    src.add_argument("--outposts", metavar="GEOJSON", default=argparse.SUPPRESS,
                     help="outposts: GeoJSON Points (lon, lat) with height_m (eye height above "
                          "ground, m, default 2) and optional range_m (m, default unlimited); "
                          "required unless --sample")
    src.add_argument("--area", metavar="S,W,N,E", default=argparse.SUPPRESS,
                     help="crop to this area of operations, degrees (default: the whole DEM)")
    src.add_argument("--resolution", metavar="M", type=float, default=argparse.SUPPRESS,
                     help="working grid spacing, metres (default: the DEM's own spacing)")
    src.add_argument("--geoid-offset", metavar="M", type=float, default=argparse.SUPPRESS,
                     help="N = ellipsoid minus geoid height, metres, for a DEM with ellipsoidal "
                          "heights: AMSL = h - N (default: heights are AMSL)")
    hv = parser.add_argument_group("hidden volume")
    hv.add_argument("--ceiling-agl", metavar="M", type=float, default=_DEFAULTS.ceiling_agl_m,
                    help="highest altitude flown, metres above ground")
    hv.add_argument("--clearance", metavar="M", type=float, default=_DEFAULTS.clearance_m,
                    help="lowest altitude flown, metres above the terrain surface")
    hv.add_argument("--hide-margin", metavar="M", type=float, default=_DEFAULTS.hide_margin_m,
                    help="metres flown below the exposure surface")
    hv.add_argument("--curvature-coeff", metavar="C", type=float,
                    default=_DEFAULTS.curvature_coeff,
                    help="earth curvature and refraction coefficient as in GDAL (0 = off)")
    parser.add_argument("-o", "--output", metavar="EXPOSURE.TIF", required=True,
                        default=argparse.SUPPRESS,
                        help="output GeoTIFF: E in metres AMSL (float32), NaN where not flyable")


def run(args) -> int:
    args.sample = getattr(args, "sample", False)
    dem, outposts_path, area = _check_args(args)
    params = ExposureParams(ceiling_agl_m=args.ceiling_agl, clearance_m=args.clearance,
                            hide_margin_m=args.hide_margin, curvature_coeff=args.curvature_coeff)
    console = Console()
    timing = {}
    with warnings.catch_warnings(record=True) as caught, _progress() as progress:
        warnings.simplefilter("always", UserWarning)
        with _stage("terrain", timing, progress):
            terrain = (sample_terrain(getattr(args, "resolution", None)) if args.sample else
                       load_dem(dem, area=area, resolution=getattr(args, "resolution", None),
                                geoid_offset=getattr(args, "geoid_offset", None)))
            outposts = (load_outposts(outposts_path, terrain) if outposts_path
                        else sample_outposts(terrain))
        with _stage("exposure", timing, progress) as update:
            surface = compute_exposure(terrain, outposts, params, progress=update)
        with _stage("write", timing, progress):
            write_grid(args.output, surface.exposure.astype(np.float32), terrain)
    for w in caught:
        console.print(f"[yellow]warning:[/] {w.message}", highlight=False)
    console.print(_summary(args.output, terrain, outposts, surface, timing))
    return 0


def _check_args(args):
    dem = getattr(args, "dem", None)
    outposts = getattr(args, "outposts", None)
    if args.sample and dem:
        raise InputError("--sample", "give either --dem or --sample, not both")
    if not args.sample and not dem:
        raise InputError("--dem", "no DEM given (use --dem FILE ... or --sample)")
    if not args.sample and not outposts:
        raise InputError("--outposts", "no outposts file given (GeoJSON Points)")
    checks = [("--resolution", getattr(args, "resolution", 1.0), "positive", lambda v: v > 0),
              ("--ceiling-agl", args.ceiling_agl, "positive", lambda v: v > 0),
              ("--clearance", args.clearance, "zero or more", lambda v: v >= 0),
              ("--hide-margin", args.hide_margin, "zero or more", lambda v: v >= 0),
              ("--curvature-coeff", args.curvature_coeff, "zero or more", lambda v: v >= 0),
              ("--geoid-offset", getattr(args, "geoid_offset", 0.0), "finite", lambda v: True)]
    for flag, value, rule, ok in checks:
        if not (np.isfinite(value) and ok(value)):
            raise InputError(flag, f"must be {rule}, got {value:g}")
    area = _parse_area(args.area) if getattr(args, "area", None) else None
    if args.sample and area is not None:
        raise InputError("--area", "cannot crop the built-in sample terrain")
    return dem, outposts, area


def _parse_area(text: str):
    try:
        south, west, north, east = (float(v) for v in text.split(","))
    except ValueError:
        raise InputError("--area", f"expected S,W,N,E in degrees, got {text!r}") from None
    return south, west, north, east  # load_dem checks the ranges


@contextmanager
def _progress():
    with Progress(SpinnerColumn(), TextColumn("{task.description:<10}"), BarColumn(),
                  TextColumn("{task.percentage:>3.0f}%"), TimeElapsedColumn(),
                  console=Console(stderr=True), transient=True) as progress:
        yield progress


@contextmanager
def _stage(name, timing, progress):
    """Time a stage; yields a ``update(done, total)`` callback for its progress bar."""
    task = progress.add_task(name, total=None)

    def update(done, total):
        progress.update(task, completed=done, total=total)

    t0 = time.perf_counter()
    yield update
    timing[name] = time.perf_counter() - t0
    progress.update(task, completed=1, total=1, visible=False)


def _summary(output, terrain, outposts, surface, timing) -> Table:
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
