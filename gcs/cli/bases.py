"""`gcs bases`: where to put the base. Ranks ground launch points that `gcs plan
--launch` accepts by the reach bound of a fleet leaving from them
(`planner.bases`), and writes them as GeoJSON, KML and a map."""

import json
import xml.etree.ElementTree as ET
from dataclasses import replace
from pathlib import Path

from common.errors import InputError
from common.fileio import check_output_dir, write_text_atomic
from gcs.cli.options import add_scenario_arguments, scenario_from_args

HELP = "suggest bases: rank hidden ground launch points by how fast a fleet covers the area"

FILES = ("bases.geojson", "bases.kml", "bases.png")


def add_arguments(parser) -> None:
    add_scenario_arguments(parser)
    parser.add_argument("-o", "--output", required=True, metavar="DIR",
                        help="output directory (created; files in it are replaced atomically)")
    parser.add_argument("--count", type=int, default=10, metavar="N",
                        help="how many bases to report")
    parser.add_argument("--base-separation", dest="base_separation", type=float, default=None,
                        metavar="M",
                        help="least distance between two reported bases, metres "
                             "(default: 500)")
    parser.add_argument("--base-spacing", dest="base_spacing", type=float, default=None,
                        metavar="M",
                        help="grid spacing of the ground points tried, metres (default: "
                             "automatic, at most 200 points over the hidden area)")


def run(args) -> int:
    if getattr(args, "launch", None):
        raise InputError("--launch", "gcs bases suggests the launch point: leave --launch out")
    # a scenario is checked as a plan's, and a plan's endurance needs a launch point:
    # one stands in for the bases tried (a scenario file's launch is ignored here)
    args.launch = ["0,0"]
    scenario = replace(scenario_from_args(args), launch=[])   # option errors first
    if args.count < 1:
        raise InputError("--count", f"must be at least 1, got {args.count}")
    if args.base_separation is not None and not args.base_separation >= 0:
        raise InputError("--base-separation",
                         f"must not be negative, got {args.base_separation}")
    if args.base_spacing is not None and not args.base_spacing > 0:
        raise InputError("--base-spacing", f"must be positive, got {args.base_spacing}")
    check_output_dir(args.output)
    from gcs.progress import console, stage_progress
    from planner.bases import SEPARATION_M, suggest_bases, suggest_sets
    from planner.pipeline import prepare

    separation = SEPARATION_M if args.base_separation is None else args.base_separation

    with stage_progress() as progress:
        ctx = prepare(scenario, progress, log=lambda text: console.print(text, markup=False))
        bases = suggest_bases(ctx, args.count, separation, args.base_spacing, progress)
        sets = suggest_sets(ctx, bases) if scenario.endurance_min is not None else []
        progress("write", 0.0)
        written = write_bases(args.output, ctx, bases)
        progress("write", 1.0)
    print(bases_table(bases, scenario.uavs, scenario.endurance_min))
    if sets:
        print(sets_table(sets, scenario.endurance_min))
    for path, what in written:
        console.print(f"  {path}  [dim]{what}[/dim]")
    return 0


def bases_table(bases, uavs, endurance_min=None) -> str:
    """The terminal table, and the ``--launch`` of the best base. On a battery
    each base's reach (`planner.bases.Base.reach_km2`), which ranks it first, and
    its bound is said to be over that ground."""
    if endurance_min is None:
        head = (f"{len(bases)} bases for {uavs} UAVs, best first (bound: no plan from there "
                "covers the targets sooner)")
    else:
        head = (f"{len(bases)} bases for {uavs} UAVs on one {endurance_min:g}-min battery, "
                "best first: the most ground one battery reaches from there (% of the "
                "ground any hidden viewpoint sees), then the lowest bound (no plan from "
                "there covers that ground sooner; the rest it does not cover at all)")
    reach = endurance_min is not None
    lines = [head, f"{'rank':>4}  {'lat,lon':<22} {'ground m':>8} {'takeoff m':>9}"
                   + (f" {'reach km²':>9} {'reach %':>7}" if reach else "") + f" {'bound min':>9}"]
    for b in bases:
        lines.append(f"{b.rank:>4}  {b.launch_arg:<22} {b.ground_m:>8.0f} {b.takeoff_m:>9.0f}"
                     + (f" {b.reach_km2:>9.2f} {b.reach_pct:>7.1f}" if reach else "")
                     + f" {b.bound_s / 60:>9.1f}")
    lines.append(f"best: --launch {bases[0].launch_arg}")
    if not any(b.inside for b in bases):
        lines.append("none of them stands in the area of operations: no ground point there "
                     "passes the launch checks")
    return "\n".join(lines)


def sets_table(sets, endurance_min) -> str:
    """What one battery reaches from the base that reaches the most, and from sets
    of bases grown from it for reach (the UAVs take them in turn)."""
    lines = [f"reach on one {endurance_min:g}-min battery: ground seen from a viewpoint "
             "flown to and back (% of the ground any hidden viewpoint sees); a plan from "
             "those bases sees all of it. Sets grown base by base, the UAVs taking them in turn:",
             f"{'bases':>5}  {'reach km²':>9} {'reach %':>7} {'bound min':>9}  --launch"]
    for s in sets:
        lines.append(f"{len(s.bases):>5}  {s.reach_km2:>9.2f} {s.reach_pct:>7.1f} "
                     f"{s.bound_s / 60:>9.1f}  {s.launch_arg}")
    if len(sets) == 1 and sets[0].reach_pct < 100.0:
        lines.append("no second base adds ground a battery reaches")
    return "\n".join(lines)


def write_bases(directory, ctx, bases) -> list:
    """bases.geojson, bases.kml and bases.png in ``directory``; [(path, what)]."""
    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    write_text_atomic(out / "bases.geojson", json.dumps(bases_geojson(bases), indent=1) + "\n")
    write_text_atomic(out / "bases.kml", bases_kml(bases))
    bases_png(out / "bases.png", ctx, bases)
    return [(out / "bases.geojson", "ranked bases (GeoJSON points)"),
            (out / "bases.kml", "ranked bases (Google Earth)"),
            (out / "bases.png", "map: hidden area, outposts, bases by rank")]


def _properties(b) -> dict:
    return {"rank": b.rank, "lat": round(b.lat, 7), "lon": round(b.lon, 7),
            "ground_amsl_m": round(b.ground_m, 1), "takeoff_amsl_m": round(b.takeoff_m, 1),
            "bound_min": round(b.bound_s / 60, 2), "launch": b.launch_arg,
            **({} if b.reach_km2 is None else {"reach_km2": b.reach_km2,
                                               "reach_pct": b.reach_pct}),
            "marker-color": "#ffffff", "marker-symbol": str(b.rank) if b.rank < 10 else "square"}


def bases_geojson(bases) -> dict:
    return {"type": "FeatureCollection", "features": [
        {"type": "Feature", "properties": _properties(b),
         "geometry": {"type": "Point", "coordinates": [round(b.lon, 7), round(b.lat, 7),
                                                       round(b.ground_m, 1)]}}
        for b in bases]}


def bases_kml(bases) -> str:
    from missions.geo import KML_NS

    ET.register_namespace("", KML_NS)

    def sub(parent, tag, text=None):
        element = ET.SubElement(parent, f"{{{KML_NS}}}{tag}")
        if text is not None:
            element.text = text
        return element

    kml = ET.Element(f"{{{KML_NS}}}kml")
    doc = sub(kml, "Document")
    sub(doc, "name", "suggested bases (gcs bases)")
    for b in bases:
        mark = sub(doc, "Placemark")
        sub(mark, "name", f"base {b.rank}")
        sub(mark, "description", f"coverage bound {b.bound_s / 60:.1f} min; ground "
                                 f"{b.ground_m:.0f} m, takeoff to {b.takeoff_m:.0f} m AMSL; "
                                 f"gcs plan --launch {b.launch_arg}")
        point = sub(mark, "Point")
        sub(point, "altitudeMode", "clampToGround")
        sub(point, "coordinates", f"{b.lon:.7f},{b.lat:.7f},0")
    ET.indent(kml)
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(kml, encoding="unicode") + "\n"


# --- the map ---------------------------------------------------------------------------
def bases_png(path, ctx, bases) -> None:
    """bases.png: the overview map's background (hidden room, outposts and their
    ranges), the area of operations, and the bases numbered by rank."""
    from gcs.plots import save_figure
    save_figure(bases_figure(ctx, bases), path)


def bases_figure(ctx, bases):
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    from common.colours import BASE_COLOUR
    from gcs.plots import draw_area_of, draw_background, lonlat_km, symbol_legend

    terrain = ctx.terrain
    fig, ax = plt.subplots(figsize=(10, 10.5), dpi=110)
    x, y = lonlat_km(terrain, [b.lon for b in bases], [b.lat for b in bases])
    im = draw_background(ax, terrain, ctx.surface, avoid=zip(x, y))
    s = ctx.scenario
    draw_area_of(ax, terrain, s.area, s.area_file, s.area_flight)
    for b, bx, by in zip(reversed(bases), x[::-1], y[::-1]):   # the best drawn on top
        top = b.rank == 1
        ax.plot(bx, by, marker="s", color="#ffd700" if top else BASE_COLOUR,
                markeredgecolor="black", markersize=16 if top else 13, zorder=12)
        ax.text(bx, by, str(b.rank), ha="center", va="center", fontsize=8 if b.rank < 10 else 6,
                fontweight="bold", zorder=13)
    best = bases[0]
    reach = ("" if best.reach_km2 is None else
             f"reaches {best.reach_km2:.2f} km² ({best.reach_pct:.1f} %) on one battery, ")
    ax.set_title(f"Suggested bases for {s.uavs} UAVs (k = {s.k}), numbered best first: "
                 f"best {reach}{best.bound_s / 60:.1f} min\n(coverage time bound from the "
                 f"base{' over that ground' if reach else ''}; --launch {best.launch_arg})")
    fig.colorbar(im, ax=ax, shrink=0.7, label="hidden ceiling above ground (m): "
                                              "room to fly unseen")
    handles, _ = ax.get_legend_handles_labels()
    handles += [Line2D([], [], linestyle="none", marker="s", color="#ffd700",
                       markeredgecolor="black", markersize=11,
                       label=f"best base (1): bound {best.bound_s / 60:.1f} min"),
                Line2D([], [], linestyle="none", marker="s", color=BASE_COLOUR,
                       markeredgecolor="black", markersize=10,
                       label="other bases, numbered by rank (lower = "
                             + ("more ground one battery reaches, then " if reach else "")
                             + "faster coverage)")]
    ax.legend(handles=handles + symbol_legend(ctx.surface, snapshots=False, base=False),
              loc="upper center", bbox_to_anchor=(0.5, -0.09), ncol=2, fontsize=8,
              framealpha=0.9)
    return fig
