"""flight.png: what was flown, where vehicles were lost, what the survivors were re-tasked to."""

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from gcs.plots import ROUTE_COLOURS, _lonlat_km, _save, draw_background  # noqa: E402


def flight_png(path, terrain, surface, plan, report: dict) -> None:
    """Recorded tracks (solid), planned routes (faint), re-planned routes (dashed),
    snapshots taken (dots), losses (crosses), and the coverage reached in the title."""
    fig, ax = plt.subplots(figsize=(10, 9), dpi=110)
    im = draw_background(ax, terrain, surface)
    colour = {v["sysid"]: ROUTE_COLOURS[i % len(ROUTE_COLOURS)]
              for i, v in enumerate(report["vehicles"])}
    planned = {r.id: r for r in plan.vehicles}
    for v in report["vehicles"]:
        c = colour[v["sysid"]]
        route = planned.get(v["vehicle"])
        if route is not None and route.waypoints:
            x, y = _lonlat_km(terrain, [w.lon for w in route.waypoints],
                              [w.lat for w in route.waypoints])
            ax.plot(x, y, "-", color=c, linewidth=0.8, alpha=0.35)
        _draw_track(ax, terrain, v, c)
    for r in report["replans"]:
        for sysid, points in r["routes"].items():
            if points:
                p = np.asarray(points, float)
                x, y = _lonlat_km(terrain, p[:, 0], p[:, 1])
                ax.plot(x, y, "--", color=colour.get(int(sysid), "black"), linewidth=1.4)
    ax.set_title(_title(report))
    fig.colorbar(im, ax=ax, shrink=0.7, label="hidden ceiling above ground (m)")
    ax.legend(loc="upper right", fontsize=8, framealpha=0.85)
    _save(fig, path)


def _draw_track(ax, terrain, v, c) -> None:
    label = f"sysid {v['sysid']} (UAV {v['vehicle']}): {v['state']}"
    if v["track"]:
        t = np.asarray(v["track"], float)
        x, y = _lonlat_km(terrain, t[:, 1], t[:, 2])
        ax.plot(x, y, "-", color=c, linewidth=1.8, label=label)
        if v["state"] == "lost":
            ax.plot(x[-1], y[-1], "X", color=c, markersize=14, markeredgecolor="black",
                    zorder=7)
            ax.annotate(f"lost {v['lost_at_s']:.0f} s", (x[-1], y[-1]), fontsize=8,
                        xytext=(6, 6), textcoords="offset points")
    else:
        ax.plot([], [], "-", color=c, label=label)
    if v["snapshots"]:
        s = v["snapshots"]
        x, y = _lonlat_km(terrain, [p["lon"] for p in s], [p["lat"] for p in s])
        ax.plot(x, y, "o", color=c, markersize=3.5, markeredgecolor="black",
                markeredgewidth=0.4, alpha=0.4 if v["state"] == "lost" else 1.0)


def _title(report) -> str:
    cov = report.get("coverage", {}).get("survivors")
    losses = len(report["losses"])
    text = f"flight: {len(report['vehicles'])} vehicles, {losses} lost, " \
           f"{len(report['replans'])} re-plan(s)"
    if cov:
        text += (f"\nk = {cov['k']}: {cov['k_covered']} of {cov['targets']} targets seen by "
                 f"{cov['required_uavs']} surviving vehicle(s) "
                 f"({100 * cov['fraction_k_covered']:.1f} %)")
    return text
