"""Pictures people would rather look at than read: overview, flight and 3-D views."""

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.colors import LightSource  # noqa: E402

from common.fileio import atomic_path  # noqa: E402

ROUTE_COLOURS = plt.get_cmap("tab10").colors


def _extent_km(terrain):
    """imshow extent of the grid in km relative to its south-west corner."""
    rows, cols = terrain.shape
    d = terrain.cell_size / 1000.0
    return (0.0, cols * d, 0.0, rows * d)


def _to_km(terrain, x, y):
    t = terrain.transform
    rows = terrain.shape[0]
    return (np.asarray(x) - t.c) / 1000.0, (np.asarray(y) - (t.f + rows * t.e)) / 1000.0


def _lonlat_km(terrain, lon, lat):
    x, y = terrain.from_lonlat(np.asarray(lon, float), np.asarray(lat, float))
    return _to_km(terrain, x, y)


def draw_background(ax, terrain, surface):
    """Hillshade, the hidden ceiling height above ground, outposts and their ranges."""
    h = np.where(np.isfinite(terrain.height), terrain.height, np.nanmin(terrain.height))
    shade = LightSource(azdeg=315, altdeg=45).hillshade(h, vert_exag=2, dx=terrain.cell_size,
                                                        dy=terrain.cell_size)
    extent = _extent_km(terrain)
    ax.imshow(shade, cmap="gray", extent=extent, origin="upper", vmin=0, vmax=1)
    hidden_agl = surface.ceiling - terrain.height
    im = ax.imshow(np.ma.masked_invalid(hidden_agl), cmap="viridis", alpha=0.45, extent=extent,
                   origin="upper", vmin=0, vmax=np.nanmax(hidden_agl) if np.isfinite(
                       hidden_agl).any() else 1)
    for o in surface.outposts:
        ox, oy = _to_km(terrain, o.x, o.y)
        ax.plot(ox, oy, marker="^", color="red", markersize=10, markeredgecolor="black",
                zorder=5)
        if np.isfinite(o.range_m):
            ax.add_patch(plt.Circle((ox, oy), o.range_m / 1000.0, fill=False, color="red",
                                    linestyle=":", linewidth=1))
    ax.set_xlim(extent[0], extent[1])
    ax.set_ylim(extent[2], extent[3])
    ax.set_xlabel("east (km)")
    ax.set_ylabel("north (km)")
    ax.set_aspect("equal")
    return im


def draw_routes(ax, terrain, plan, linestyle="-", label_prefix="UAV", alpha=1.0):
    for i, vehicle in enumerate(plan.vehicles):
        colour = ROUTE_COLOURS[i % len(ROUTE_COLOURS)]
        lon = [w.lon for w in vehicle.waypoints]
        lat = [w.lat for w in vehicle.waypoints]
        if not lon:
            continue
        x, y = _lonlat_km(terrain, lon, lat)
        ax.plot(x, y, linestyle, color=colour, linewidth=1.6, alpha=alpha,
                label=f"{label_prefix} {vehicle.id}: {vehicle.coverage_time_s / 60:.1f} min")
        snaps = np.array([w.snapshot for w in vehicle.waypoints])
        ax.plot(x[snaps], y[snaps], "o", color=colour, markersize=3.5,
                markeredgecolor="black", markeredgewidth=0.4, alpha=alpha)
        if vehicle.launch is not None:
            lx, ly = _lonlat_km(terrain, vehicle.launch.lon, vehicle.launch.lat)
            ax.plot(lx, ly, marker="s", color="white", markeredgecolor="black", markersize=8,
                    zorder=6)


def overview_png(path, terrain, surface, plan) -> None:
    """overview.png: where one can hide, who watches, and every route."""
    fig, ax = plt.subplots(figsize=(10, 9), dpi=110)
    im = draw_background(ax, terrain, surface)
    draw_routes(ax, terrain, plan)
    m = plan.metrics
    ax.set_title(f"{plan.method.upper()}: {len(plan.vehicles)} UAVs, k = {m.get('k', 0)}, "
                 f"coverage time {m.get('coverage_time_s', float('nan')) / 60:.1f} min "
                 f"(lower bound {m.get('lower_bound_s', float('nan')) / 60:.1f} min)")
    fig.colorbar(im, ax=ax, shrink=0.7, label="hidden ceiling above ground (m)")
    ax.legend(loc="upper right", fontsize=8, framealpha=0.85)
    _save(fig, path)


def view3d_png(path, terrain, surface, plan, max_cells=160) -> None:
    """view3d.png: terrain, the exposure surface above it and the routes in 3-D
    (the source paper's Fig. 4), decimated to at most ``max_cells`` per side."""
    step = max(1, int(np.ceil(max(terrain.shape) / max_cells)))
    rows = np.arange(0, terrain.shape[0], step)
    cols = np.arange(0, terrain.shape[1], step)
    x, y = _to_km(terrain, *terrain.xy(*np.meshgrid(rows, cols, indexing="ij")))
    ground = terrain.height[np.ix_(rows, cols)]
    ceiling = surface.ceiling[np.ix_(rows, cols)]
    fig = plt.figure(figsize=(11, 8), dpi=110)
    # draw in call order (terrain, ceiling, routes): matplotlib's depth sort would
    # bury the routes under the translucent ceiling they fly just below
    ax = fig.add_subplot(projection="3d", computed_zorder=False)
    ax.plot_surface(x, y, ground, cmap="gist_earth", linewidth=0, antialiased=False,
                    alpha=0.95)
    ax.plot_wireframe(x, y, ceiling, color="tab:blue", alpha=0.35, linewidth=0.4,
                      rstride=2, cstride=2)
    for i, vehicle in enumerate(plan.vehicles):
        if not vehicle.waypoints:
            continue
        w = vehicle.waypoints
        vx, vy = _lonlat_km(terrain, [p.lon for p in w], [p.lat for p in w])
        ax.plot(vx, vy, [p.alt_amsl for p in w], color=ROUTE_COLOURS[i % len(ROUTE_COLOURS)],
                linewidth=2.0, label=f"UAV {vehicle.id}")
    for o in surface.outposts:
        ox, oy = _to_km(terrain, o.x, o.y)
        ax.scatter([ox], [oy], [float(terrain.ground(o.x, o.y)[0]) + o.height_m + 20],
                   marker="^", color="red", s=60, depthshade=False)
    ax.set_xlabel("east (km)")
    ax.set_ylabel("north (km)")
    ax.set_zlabel("altitude AMSL (m)")
    ax.set_box_aspect((np.ptp(x), np.ptp(y), 0.25 * max(np.ptp(x), np.ptp(y))))
    ax.view_init(elev=35, azim=-60)
    ax.set_title("terrain, hidden ceiling (blue mesh: fly below it) and routes")
    ax.legend(loc="upper left", fontsize=8)
    _save(fig, path)


def _save(fig, path) -> None:
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", bbox_inches="tight")
    plt.close(fig)
