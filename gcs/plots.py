"""Pictures people would rather look at than read: overview, flight and 3-D views.

Every map has what a reader needs to match it to QGroundControl or a paper map:
a legend entry for every symbol, outpost names beside their ranges, a latitude /
longitude graticule (the axes are km from the grid's south-west corner, on the
plan's projected grid), a scale bar and an arrow to true north. Colours are
`common.colours`, the same as in the KML and GeoJSON files. Altitudes say their
frame (AMSL, above ground).
"""

import math

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.colors import LightSource, Normalize  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402
from matplotlib.patches import Patch  # noqa: E402

from common.colours import (  # noqa: E402
    BASE_COLOUR,
    BEYOND_COLOUR,
    OUTPOST_COLOUR,
    VEHICLE_COLOURS,
    vehicle_colour,
)
from common.fileio import atomic_path  # noqa: E402

ROUTE_COLOURS = VEHICLE_COLOURS          # by plan vehicle id: vehicle_colour(id)
CEILING_CMAP = "viridis"
EXPOSED_LABEL = "grey: no hidden room (seen, or ceiling below clearance)"


def _extent_km(terrain):
    """imshow extent of the grid in km relative to its south-west corner."""
    rows, cols = terrain.shape
    d = terrain.cell_size / 1000.0
    return (0.0, cols * d, 0.0, rows * d)


def _to_km(terrain, x, y):
    t = terrain.transform
    rows = terrain.shape[0]
    return (np.asarray(x) - t.c) / 1000.0, (np.asarray(y) - (t.f + rows * t.e)) / 1000.0


def _from_km(terrain, kx, ky):
    t = terrain.transform
    rows = terrain.shape[0]
    return np.asarray(kx) * 1000.0 + t.c, np.asarray(ky) * 1000.0 + (t.f + rows * t.e)


def lonlat_km(terrain, lon, lat):
    x, y = terrain.from_lonlat(np.asarray(lon, float), np.asarray(lat, float))
    return _to_km(terrain, x, y)


def draw_background(ax, terrain, surface, names=True, avoid=()):
    """Hillshade, the hidden ceiling height above ground, outposts (named) and their
    ranges, a graticule, a scale bar and a north arrow (clear of the points
    ``avoid``, km: `draw_north_arrow`). Returns the ceiling image."""
    h = np.where(np.isfinite(terrain.height), terrain.height, np.nanmin(terrain.height))
    shade = LightSource(azdeg=315, altdeg=45).hillshade(h, vert_exag=2, dx=terrain.cell_size,
                                                        dy=terrain.cell_size)
    extent = _extent_km(terrain)
    avoid = np.asarray(list(avoid), float).reshape(-1, 2)     # read twice below
    ax.imshow(shade, cmap="gray", extent=extent, origin="upper", vmin=0, vmax=1)
    hidden_agl = surface.ceiling - terrain.height
    im = ax.imshow(np.ma.masked_invalid(hidden_agl), cmap=CEILING_CMAP, alpha=0.45,
                   extent=extent, origin="upper", vmin=0,
                   vmax=np.nanmax(hidden_agl) if np.isfinite(hidden_agl).any() else 1)
    # a range's label keeps off the bases and off every post's name (they overlapped)
    avoid_labels = np.concatenate([avoid, *(_name_points(terrain, extent, o, _post_name(o, n))
                                            for n, o in enumerate(surface.outposts))])
    for n, o in enumerate(surface.outposts):
        ox, oy = _to_km(terrain, o.x, o.y)
        ax.plot(ox, oy, marker="^", color=OUTPOST_COLOUR, markersize=10,
                markeredgecolor="black", zorder=8)
        name = getattr(o, "name", None) or f"outpost {n + 1}"
        if names:
            right = ox > (extent[0] + extent[1]) / 2       # keep the label on the map
            ax.annotate(_post_name(o, n), (ox, oy), xytext=(-7 if right else 7, -4),
                        textcoords="offset points", ha="right" if right else "left",
                        fontsize=8, fontweight="bold", color="black", zorder=9,
                        bbox=dict(boxstyle="round,pad=0.15", fc="white", ec=OUTPOST_COLOUR,
                                  lw=0.6, alpha=0.85))
        if np.isfinite(o.range_m):
            r = o.range_m / 1000.0
            ax.add_patch(plt.Circle((ox, oy), r, fill=False, color=OUTPOST_COLOUR,
                                    linestyle=":", linewidth=1.2, zorder=4))
            if names:
                _label_range(ax, extent, ox, oy, r, f"{name}: {o.range_m / 1000:g} km range",
                             avoid_labels)
    ax.set_xlim(extent[0], extent[1])
    ax.set_ylim(extent[2], extent[3])
    ax.set_xlabel("east (km from the grid's south-west corner)")
    ax.set_ylabel("north (km)")
    ax.set_aspect("equal")
    draw_graticule(ax, terrain)
    draw_scale_bar(ax, extent)
    draw_north_arrow(ax, terrain, avoid)
    return im


def _post_name(o, n) -> str:
    """A post's label beside it: its name (or number) and its range."""
    name = getattr(o, "name", None) or f"outpost {n + 1}"
    rng = f"{o.range_m / 1000:g} km range" if np.isfinite(o.range_m) else "range unlimited"
    return f"{name} ({rng})"


def _name_points(terrain, extent, o, text) -> np.ndarray:
    """(n, 2) km: points along a post's name label (bold 8-pt, beside it, towards
    the map's middle), for other labels to keep off."""
    ox, oy = _to_km(terrain, o.x, o.y)
    width = 1.2 * LABEL_CHAR_SHARE * len(text) * (extent[1] - extent[0])
    side = -1.0 if ox > (extent[0] + extent[1]) / 2 else 1.0
    return np.stack([ox + side * np.linspace(0.0, width, 12), np.full(12, float(oy))], axis=1)


#: a range label's size on the map, per character and in height, as shares of the
#: map's width and height (7-pt italic on the 10-inch maps); how far (share of the
#: map's shorter side) it keeps from a point to avoid (a base's square)
LABEL_CHAR_SHARE, LABEL_HEIGHT_SHARE, LABEL_CLEAR = 0.009, 0.025, 0.02


def _label_range(ax, extent, ox, oy, r, text, avoid=()) -> None:
    """The range's name on its circle, at the first point of it inside the map
    (searching from the top clockwise) where the label covers none of the points
    ``avoid`` (km: what the map draws on top, bases, which hid the label), so the
    circle can be told from others; where every place covers one, the first."""
    x0, x1, y0, y1 = extent
    pad = 0.04 * max(x1 - x0, y1 - y0)
    points = np.asarray(avoid, float).reshape(-1, 2)
    width = LABEL_CHAR_SHARE * len(text) * (x1 - x0)
    height, near = LABEL_HEIGHT_SHARE * (y1 - y0), LABEL_CLEAR * min(x1 - x0, y1 - y0)
    first = None
    for deg in np.arange(60, 60 + 360, 10):
        a = math.radians(deg)
        px, py = ox + r * math.cos(a), oy + r * math.sin(a)
        if not (x0 + pad < px < x1 - pad and y0 + pad < py < y1 - pad):
            continue
        right = px > (x0 + x1) / 2
        first = first or (px, py, right)
        lo, hi = (px - width, px) if right else (px, px + width)
        if not ((points[:, 0] > lo - near) & (points[:, 0] < hi + near)
                & (points[:, 1] > py - near) & (points[:, 1] < py + height + near)).any():
            first = (px, py, right)
            break
    if first is None:
        return
    px, py, right = first
    ax.annotate(text, (px, py), fontsize=7, color=OUTPOST_COLOUR, style="italic",
                ha="right" if right else "left", va="bottom", zorder=9,
                xytext=(-3 if right else 3, 3), textcoords="offset points",
                bbox=dict(boxstyle="round,pad=0.1", fc="white", ec="none", alpha=0.7))


def _nice_step(span: float, target: int = 4) -> float:
    """A round graticule step (degrees) giving about ``target`` lines over ``span``."""
    raw = span / max(target, 1)
    for step in (0.001, 0.002, 0.005, 0.01, 0.02, 0.025, 0.05, 0.1, 0.2, 0.25, 0.5, 1.0,
                 2.0, 5.0, 10.0):
        if step >= raw:
            return step
    return 10.0


def _fmt_deg(value: float, step: float, pos: str, neg: str) -> str:
    decimals = max(0, -int(math.floor(math.log10(step))) + (1 if step * 10 ** -math.floor(
        math.log10(step)) not in (1.0, 2.0, 5.0) else 0))
    return f"{abs(value):.{decimals}f}°{pos if value >= 0 else neg}"


#: the part of a map's width (and height) at its lower-left corner left without
#: graticule labels: there a longitude label along the bottom and a latitude label
#: up the left side overlapped
GRATICULE_CORNER = 0.1


def draw_graticule(ax, terrain) -> None:
    """Latitude and longitude lines (WGS 84), labelled where they leave the map."""
    x0, x1, y0, y1 = _extent_km(terrain)
    kx, ky = np.meshgrid(np.linspace(x0, x1, 5), np.linspace(y0, y1, 5))
    lon, lat = terrain.to_lonlat(*_from_km(terrain, kx.ravel(), ky.ravel()))
    lon, lat = np.asarray(lon), np.asarray(lat)
    step = _nice_step(max(np.ptp(lon), np.ptp(lat)), target=5)
    style = dict(color="black", linewidth=0.5, alpha=0.45, zorder=3, linestyle="--")
    label = dict(fontsize=7, color="black", zorder=9,
                 bbox=dict(boxstyle="round,pad=0.1", fc="white", ec="none", alpha=0.75))
    corner = GRATICULE_CORNER
    fine = np.linspace(lat.min() - step, lat.max() + step, 60)
    for value in np.arange(math.floor(lon.min() / step) * step, lon.max() + step, step):
        x, y = lonlat_km(terrain, np.full_like(fine, value), fine)
        ax.plot(x, y, **style)
        bottom = _crossing(x, y, y0, along_y=True)
        # none in the corners, where a longitude and a latitude label would collide
        if bottom is not None and x0 + corner * (x1 - x0) < bottom < x1:
            ax.text(bottom, y0, _fmt_deg(value, step, "E", "W"), ha="center", va="bottom",
                    **label)
    fine = np.linspace(lon.min() - step, lon.max() + step, 60)
    for value in np.arange(math.floor(lat.min() / step) * step, lat.max() + step, step):
        x, y = lonlat_km(terrain, fine, np.full_like(fine, value))
        ax.plot(x, y, **style)
        left = _crossing(y, x, x0, along_y=True)
        if left is not None and y0 + corner * (y1 - y0) < left < y1:
            ax.text(x0, left, _fmt_deg(value, step, "N", "S"), ha="left", va="center",
                    rotation=90, **label)
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)


def _crossing(a, b, level, along_y):
    """Where the polyline (a, b) crosses b == level: the a there (None if it does not)."""
    b = np.asarray(b)
    a = np.asarray(a)
    s = np.sign(b - level)
    idx = np.where(s[:-1] * s[1:] <= 0)[0]
    if not len(idx):
        return None
    i = idx[0]
    if b[i + 1] == b[i]:
        return float(a[i])
    f = (level - b[i]) / (b[i + 1] - b[i])
    return float(a[i] + f * (a[i + 1] - a[i]))


def draw_scale_bar(ax, extent) -> None:
    """A round-length bar in the lower left, labelled in km or m."""
    x0, x1, y0, y1 = extent
    width = x1 - x0
    length = _nice_step(width / 1.0, target=5) if width < 1000 else width / 5
    for candidate in (0.1, 0.2, 0.25, 0.5, 1, 2, 2.5, 5, 10, 20, 25, 50, 100):
        if candidate >= width / 6:
            length = candidate
            break
    bx, by = x0 + 0.05 * width, y0 + 0.06 * (y1 - y0)
    h = 0.012 * (y1 - y0)
    ax.add_patch(plt.Rectangle((bx - 0.01 * width, by - 2.2 * h), length + 0.02 * width,
                               5.6 * h, fc="white", ec="none", alpha=0.75, zorder=9))
    for i in range(2):
        ax.add_patch(plt.Rectangle((bx + i * length / 2, by), length / 2, h,
                                   fc="black" if i == 0 else "white", ec="black", lw=0.8,
                                   zorder=10))
    text = f"{length:g} km" if length >= 1 else f"{length * 1000:g} m"
    ax.text(bx + length / 2, by + 1.4 * h, text, ha="center", va="bottom", fontsize=8,
            zorder=10)


def north_angle(terrain) -> float:
    """Angle (radians, counter-clockwise from the grid's +y) of true north at the
    grid's centre (the meridian convergence of its projection)."""
    rows, cols = terrain.shape
    cx, cy = terrain.xy(rows / 2, cols / 2)
    lon, lat = terrain.to_lonlat(cx, cy)
    nx, ny = terrain.from_lonlat(lon, lat + 0.01)
    return math.atan2(-(nx - cx), ny - cy)


#: where a north arrow may stand, as fractions of a map's width and height, in the
#: order tried: the upper left, the upper right, the lower right
NORTH_PLACES = ((0.07, 0.83), (0.93, 0.83), (0.93, 0.12))
#: the part of a map's smaller side that a north arrow keeps from the points it avoids
NORTH_CLEAR = 0.12


def draw_north_arrow(ax, terrain, avoid=()) -> None:
    """An arrow to true north, with "N": in the upper left unless one of the points
    ``avoid`` ((x, y) km: what the map draws on top, bases) stands there, then at
    the first place of `NORTH_PLACES` clear of them (bases sat on the arrow)."""
    x0, x1, y0, y1 = _extent_km(terrain)
    side = min(x1 - x0, y1 - y0)
    size = 0.07 * side
    a = north_angle(terrain)
    points = np.asarray(list(avoid), float).reshape(-1, 2)
    dx, dy = -size * math.sin(a), size * math.cos(a)
    for fx, fy in NORTH_PLACES:
        bx, by = x0 + fx * (x1 - x0), y0 + fy * (y1 - y0)
        # the arrow from its foot to its "N"
        along = np.linspace(0.0, 1.4, 8)[:, None] * np.array([dx, dy]) + np.array([bx, by])
        if not len(points) or np.min(np.hypot(*(points[:, None, :] - along[None]).T)) \
                > NORTH_CLEAR * side:
            break
    else:
        bx, by = x0 + NORTH_PLACES[0][0] * (x1 - x0), y0 + NORTH_PLACES[0][1] * (y1 - y0)
    ax.annotate("", xy=(bx + dx, by + dy), xytext=(bx, by), zorder=10,
                arrowprops=dict(arrowstyle="-|>", color="black", lw=2, mutation_scale=15))
    ax.text(bx + 1.25 * dx, by + 1.25 * dy, "N", ha="center", va="bottom", fontsize=11,
            fontweight="bold", zorder=10,
            bbox=dict(boxstyle="circle,pad=0.15", fc="white", ec="none", alpha=0.75))


def symbol_legend(surface, snapshots=True, base=True) -> list:
    """Legend handles for the symbols every map shares."""
    handles = []
    if snapshots:
        handles.append(Line2D([], [], linestyle="none", marker="o", color="grey",
                              markeredgecolor="black", markeredgewidth=0.4, markersize=5,
                              label="snapshot (in the UAV's colour)"))
    if base:
        handles.append(Line2D([], [], linestyle="none", marker="s", color=BASE_COLOUR,
                              markeredgecolor="black", markersize=8,
                              label="base: launch and landing point"))
    if surface.outposts:
        handles.append(Line2D([], [], linestyle="none", marker="^", color=OUTPOST_COLOUR,
                              markeredgecolor="black", markersize=9, label="outpost (named)"))
        if any(np.isfinite(o.range_m) for o in surface.outposts):
            handles.append(Line2D([], [], linestyle=":", color=OUTPOST_COLOUR, linewidth=1.2,
                                  label="outpost detection range"))
    handles.append(Patch(facecolor="#9a9a9a", edgecolor="black", linewidth=0.4,
                         label=EXPOSED_LABEL))
    return handles


def draw_routes(ax, terrain, plan, linestyle="-", label_prefix="UAV", alpha=1.0):
    for vehicle in plan.vehicles:
        colour = vehicle_colour(vehicle.id)
        lon = [w.lon for w in vehicle.waypoints]
        lat = [w.lat for w in vehicle.waypoints]
        if not lon:
            continue
        x, y = lonlat_km(terrain, lon, lat)
        waits = vehicle.takeoff_s + sum(w.hold_s for w in vehicle.waypoints)
        sorties = f", {len(vehicle.sorties)} sorties" if len(vehicle.sorties) > 1 else ""
        ax.plot(x, y, linestyle, color=colour, linewidth=1.6, alpha=alpha, zorder=5,
                label=f"{label_prefix} {vehicle.id}: takeoff at {vehicle.takeoff_s:.0f} s, "
                      f"{sum(1 for w in vehicle.waypoints if w.snapshot)} snapshots by "
                      f"{vehicle.coverage_time_s / 60:.1f} min, waits {waits:.0f} s{sorties}")
        snaps = np.array([w.snapshot for w in vehicle.waypoints])
        ax.plot(x[snaps], y[snaps], "o", color=colour, markersize=3.5, zorder=6,
                markeredgecolor="black", markeredgewidth=0.4, alpha=alpha)
    draw_bases(ax, terrain, plan)


def draw_area(ax, terrain, plan):
    """The plan's area of operations (``--area`` box, ``--area-file`` polygon while
    its file is still there), dashed; labelled for the legend. Its legend handle
    (None: not drawn)."""
    p = plan.params
    return draw_area_of(ax, terrain, p.get("area"), p.get("area_file"),
                        bool(p.get("area_flight")))


#: points along each side of the --area box: a parallel or meridian is a curve on
#: a projected map
BOX_STEPS = 32


def draw_area_of(ax, terrain, box=None, area_file=None, area_flight=False):
    """The area of operations, dashed: the (south, west, north, east) ``box``, which
    both targets and flight stay inside (the DEM may be read wider, around an
    outpost outside it, and the map with it), and the ``area_file`` polygon when
    the file is there. Its legend handle, None when there is neither."""
    from pathlib import Path

    rings = []
    if box is not None:
        s, w, n, e = box
        t = np.linspace(0.0, 1.0, BOX_STEPS)
        lon = np.concatenate([w + (e - w) * t, np.full(BOX_STEPS, e), e - (e - w) * t,
                              np.full(BOX_STEPS, w)])
        lat = np.concatenate([np.full(BOX_STEPS, s), s + (n - s) * t, np.full(BOX_STEPS, n),
                              n - (n - s) * t])
        rings.append(np.stack([lon, lat], axis=1))
    if area_file and Path(area_file).is_file():
        from planner.terrain.area import read_area
        rings += [ring for polygon in read_area(area_file) for ring in polygon]
    flight = area_flight or (box is not None and not area_file)
    label = "area of operations (targets" + (" and flight" if flight else "") + " inside)"
    handle = None
    for ring in rings:
        x, y = lonlat_km(terrain, ring[:, 0], ring[:, 1])
        line, = ax.plot(x, y, linestyle=(0, (5, 3)), color="black", linewidth=1.4,
                        zorder=4, label=label)
        handle, label = handle or line, None
    return handle


def draw_bases(ax, terrain, plan) -> None:
    """Launch points as white squares, on top of every route."""
    for vehicle in plan.vehicles:
        if vehicle.launch is not None:
            lx, ly = lonlat_km(terrain, vehicle.launch.lon, vehicle.launch.lat)
            ax.plot(lx, ly, marker="s", color=BASE_COLOUR, markeredgecolor="black",
                    markersize=8, zorder=12)


#: hatching of ground in the area of operations that no snapshot will see, by reason
#: (`planner.visibility.unseen`)
UNSEEN_HATCHES = {1: "....", 2: "////", 3: "xxxx", 4: "\\\\"}


def draw_unseen(ax, terrain, unseen) -> list:
    """Hatch the ground of the area of operations that is not a target, one pattern
    per reason; the legend handles of the reasons present."""
    from planner.visibility.unseen import REASONS

    if unseen is None:
        return []
    handles = []
    extent = _extent_km(terrain)
    rows, cols = terrain.shape
    d = terrain.cell_size / 1000.0
    x = extent[0] + (np.arange(cols) + 0.5) * d
    y = extent[3] - (np.arange(rows) + 0.5) * d
    for code, hatch in UNSEEN_HATCHES.items():
        mask = unseen == code
        if not mask.any():
            continue
        ax.contourf(x, y, mask.astype(float), levels=[0.5, 1.5], colors="none",
                    hatches=[hatch], zorder=3)
        handles.append(Patch(facecolor="white", edgecolor="black", hatch=hatch,
                             linewidth=0.4, label=f"not seen: {REASONS[code]}"))
    return handles


def draw_beyond_battery(ax, terrain, plan) -> None:
    """The viewpoints no base reaches and leaves on one battery (plan.json
    ``battery.beyond_battery_at``), crossed out: their targets lose those sightings."""
    at = (plan.metrics.get("battery") or {}).get("beyond_battery_at") or []
    if not at:
        return
    lat, lon = np.array(at, float).T
    x, y = lonlat_km(terrain, lon, lat)
    ax.plot(x, y, linestyle="none", marker="D", color=BEYOND_COLOUR, markersize=3.5,
            markeredgecolor="white", markeredgewidth=0.5, zorder=7,
            label=f"viewpoint beyond one battery ({len(at)}): not flown to")


def draw_link(ax, terrain, plan) -> None:
    """The radio link the plan predicts (`planner.link`): its antennas, each stretch
    of route out of their contact (a vehicle's ``silences`` along its trajectory) and
    the check-ins of --max-silence."""
    link = plan.metrics.get("link")
    if not link:
        return
    lat, lon, _ = np.array(link["antennas"], float).reshape(-1, 3).T
    ax.plot(*lonlat_km(terrain, lon, lat), linestyle="none", marker="^", color="white",
            markersize=6, markeredgecolor="black", zorder=9, label="radio antenna")
    label = (f"out of radio contact (predicted): {100 * link['share']:.0f} % of airborne "
             f"time, longest {link['longest_s']:.0f} s")
    for vehicle in plan.vehicles:
        rows = np.asarray(vehicle.trajectory, float).reshape(-1, 4)
        for a, b in vehicle.silences:
            t = np.arange(a, b + 1.0)
            x, y = lonlat_km(terrain, np.interp(t, rows[:, 0], rows[:, 1]),
                             np.interp(t, rows[:, 0], rows[:, 2]))
            ax.plot(x, y, color="black", linewidth=5.0, alpha=0.45, zorder=4.5, label=label,
                    solid_capstyle="butt")
            label = None
    at = [p for checks in (link.get("max_silence") or {}).get("at", []) for p in checks]
    if at:
        lat, lon, _ = np.array(at, float).T
        ax.plot(*lonlat_km(terrain, lon, lat), linestyle="none", marker="*", color="gold",
                markersize=10, markeredgecolor="black", zorder=8,
                label=f"check-in in radio contact ({len(at)}, --max-silence)")


def battery_title(plan) -> str:
    """One line on what a battery allows, for a map's title ('' without an endurance)."""
    b = plan.metrics.get("battery") or {}
    if b.get("endurance_min") is None:
        return ""
    return (f"battery {b['endurance_min']:g} min ({b['reserve_pct']:g} % kept): longest "
            f"flight {b['longest_flight_s'] / 60:.1f} min; {b.get('beyond_battery', 0)} "
            "viewpoints beyond it")


def overview_png(path, terrain, surface, plan, unseen=None) -> None:
    """overview.png: where one can hide, who watches, every route, and the ground no
    snapshot sees (``unseen``: `planner.visibility.unseen_reasons`)."""
    save_figure(overview_figure(terrain, surface, plan, unseen), path)


def overview_figure(terrain, surface, plan, unseen=None):
    fig, ax = plt.subplots(figsize=(10, 10.5), dpi=110)
    im = draw_background(ax, terrain, surface)
    draw_area(ax, terrain, plan)
    unseen_handles = draw_unseen(ax, terrain, unseen)
    draw_routes(ax, terrain, plan)
    draw_link(ax, terrain, plan)
    draw_beyond_battery(ax, terrain, plan)
    m = plan.metrics
    title = (f"{plan.method.upper()}: {len(plan.vehicles)} UAVs, k = {m.get('k', 0)}, "
             f"coverage time {m.get('coverage_time_s', float('nan')) / 60:.1f} min "
             f"(lower bound {m.get('lower_bound_s', float('nan')) / 60:.1f} min"
             + (f" over the {m['bound_targets_pct']:.0f} % of targets one battery reaches"
                if m.get("bound_targets_pct", 100.0) < 100.0 else "") + ")")
    a = m.get("area")
    if a:
        title += (f"\narea {a['area_km2']:.1f} km²: {a['visible']['pct']:.0f} % seen from "
                  f"reachable hidden viewpoints, {a['planned']['pct']:.0f} % planned")
    if battery_title(plan):
        title += "\n" + battery_title(plan)
    if not plan.outposts:
        title += "\nno observers: planned with no outposts"
    ax.set_title(title, fontsize=10)
    fig.colorbar(im, ax=ax, shrink=0.7, label="hidden ceiling above ground (m): "
                                              "room to fly unseen")
    handles, _ = ax.get_legend_handles_labels()
    ax.legend(handles=handles + symbol_legend(surface) + unseen_handles, loc="upper center",
              bbox_to_anchor=(0.5, -0.09), ncol=2, fontsize=8, framealpha=0.9)
    return fig


def vertical_exaggeration(x_km, y_km, z_m, target: float = 0.25) -> float:
    """A round vertical exaggeration that makes the relief about ``target`` of the
    larger horizontal side tall (at least 1)."""
    horizontal = max(np.ptp(x_km), np.ptp(y_km)) * 1000.0
    relief = max(float(np.nanmax(z_m) - np.nanmin(z_m)), 1.0)
    raw = max(1.0, target * horizontal / relief)
    for nice in (1, 1.5, 2, 2.5, 3, 4, 5, 6, 8, 10, 12, 15, 20, 25, 30, 40, 50):
        if nice >= raw:
            return float(nice)
    return float(round(raw))


def view3d_png(path, terrain, surface, plan, max_cells=160) -> None:
    """view3d.png: terrain, the exposure surface above it and the routes in 3-D
    (the source paper's Fig. 4), decimated to at most ``max_cells`` per side, with
    the terrain's colour bar and the vertical exaggeration in the title."""
    save_figure(view3d_figure(terrain, surface, plan, max_cells), path)


def view3d_figure(terrain, surface, plan, max_cells=160):
    step = max(1, int(np.ceil(max(terrain.shape) / max_cells)))
    rows = np.arange(0, terrain.shape[0], step)
    cols = np.arange(0, terrain.shape[1], step)
    x, y = _to_km(terrain, *terrain.xy(*np.meshgrid(rows, cols, indexing="ij")))
    ground = terrain.height[np.ix_(rows, cols)]
    ceiling = surface.ceiling[np.ix_(rows, cols)]
    fig = plt.figure(figsize=(12, 8.5), dpi=110)
    # draw in call order (terrain, ceiling, routes): matplotlib's depth sort would
    # bury the routes under the translucent ceiling they fly just below
    ax = fig.add_subplot(projection="3d", computed_zorder=False)
    norm = Normalize(np.nanmin(ground), np.nanmax(ground))
    ax.plot_surface(x, y, ground, cmap="gist_earth", norm=norm, linewidth=0,
                    antialiased=False, alpha=0.95)
    ax.plot_wireframe(x, y, ceiling, color="#08306b", alpha=0.6, linewidth=0.5,
                      rstride=2, cstride=2)
    for vehicle in plan.vehicles:
        if not vehicle.waypoints:
            continue
        w = vehicle.waypoints
        vx, vy = lonlat_km(terrain, [p.lon for p in w], [p.lat for p in w])
        ax.plot(vx, vy, [p.alt_amsl for p in w], color=vehicle_colour(vehicle.id),
                linewidth=2.2, label=f"UAV {vehicle.id} route")
    for n, o in enumerate(surface.outposts):
        ox, oy = _to_km(terrain, o.x, o.y)
        z = float(terrain.ground(o.x, o.y)[0]) + o.height_m + 20
        ax.scatter([ox], [oy], [z], marker="^", color=OUTPOST_COLOUR, s=70, depthshade=False,
                   edgecolors="black")
        ax.text(ox, oy, z + 40, getattr(o, "name", None) or f"outpost {n + 1}", fontsize=8,
                color="black", zorder=20)
    for vehicle in plan.vehicles:
        if vehicle.launch is not None:
            lx, ly = lonlat_km(terrain, vehicle.launch.lon, vehicle.launch.lat)
            ax.scatter([lx], [ly], [vehicle.launch.alt_amsl], marker="s", color=BASE_COLOUR,
                       edgecolors="black", s=60, depthshade=False)
    ax.set_xlabel("east (km)")
    ax.set_ylabel("north (km)")
    ax.set_zlabel("altitude AMSL (m)")
    zs = np.concatenate([ground[np.isfinite(ground)], ceiling[np.isfinite(ceiling)]])
    ve = vertical_exaggeration(x, y, zs)
    relief_km = max(float(np.ptp(zs)), 1.0) / 1000.0
    ax.set_box_aspect((np.ptp(x), np.ptp(y), ve * relief_km))
    ax.view_init(elev=35, azim=-60)
    ax.set_title(f"terrain, hidden ceiling (dark blue mesh: fly below it) and routes\n"
                 f"vertical exaggeration × {ve:g}", fontsize=11)
    sm = plt.cm.ScalarMappable(norm=norm, cmap="gist_earth")
    fig.colorbar(sm, ax=ax, shrink=0.55, pad=0.08, label="terrain altitude AMSL (m)")
    handles, _ = ax.get_legend_handles_labels()
    handles += [Line2D([], [], color="#08306b", linewidth=1, label="hidden ceiling (mesh)"),
                Line2D([], [], linestyle="none", marker="^", color=OUTPOST_COLOUR,
                       markeredgecolor="black", markersize=8, label="outpost"),
                Line2D([], [], linestyle="none", marker="s", color=BASE_COLOUR,
                       markeredgecolor="black", markersize=7, label="base")]
    ax.legend(handles=handles, loc="upper left", fontsize=8)
    return fig


def save_figure(fig, path) -> None:
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", bbox_inches="tight")
    plt.close(fig)
