"""flight.png: what was flown, where vehicles were lost, what the survivors were
re-tasked to; a timeline of each vehicle and its altitude against the terrain and
the hidden ceiling.

Times are *mission time*: seconds on the vehicles' own clocks since the flight
began (GLOBAL_POSITION_INT ``time_boot_ms``, the fifth column of a track sample),
which is what the plan's times and ``gcs sim --kill SYSID@Ts`` count. In a
sped-up simulation it runs faster than the wall clock that ``flight.json``'s
``t_s`` fields count; with real vehicles the two agree. A report without vehicle
times (an older ``flight.json``) is drawn on wall time and says so.
"""

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402
from matplotlib.patches import Patch  # noqa: E402

from common.colours import vehicle_colour  # noqa: E402
from gcs.guard import hold_spans  # noqa: E402
from gcs.plots import (  # noqa: E402
    draw_area,
    draw_background,
    draw_bases,
    lonlat_km,
    save_figure,
    symbol_legend,
)
from planner.terrain.grid import bilinear  # noqa: E402

TERRAIN_FILL = "#a0785a"
CEILING_LINE = "#08306b"
GUARD_COLOUR = "#ffd700"       # gold, hatched: no vehicle has it
REPLAN_SHADE = "#bdbdbd"
SILENT_SHADE = "#9ecae1"
SILENT_LABEL = "out of contact: no reports (where it flew is not known)"


def unheard(v) -> np.ndarray:
    """bool per pair of successive track samples: whether the vehicle was out of
    contact between them (a silence of its ``out_of_contact`` lies between the two).
    A line drawn there is no flown path: a shadow of 15 minutes was drawn as a
    straight flight through the valley under it."""
    t = np.asarray(v["track"], float)[:, 0] if v["track"] else np.zeros(0)
    gap = np.zeros(max(len(t) - 1, 0), bool)
    for quiet in v.get("out_of_contact") or []:
        # it fell silent after the one and was heard again by the other (its first
        # report then may come a moment before the loop that marks the silence over)
        if quiet.get("to_s") is not None:         # still silent: the track ends there
            gap |= (t[:-1] <= quiet["from_s"] + 0.01) & (t[1:] > quiet["from_s"])
    return gap


def broken(values, gap) -> np.ndarray:
    """``values`` (per track sample, along the first axis) with NaN between the two
    samples of each ``gap`` (`unheard`), so that a line drawn through them stops."""
    values = np.asarray(values, float)
    return np.insert(values, np.flatnonzero(gap) + 1, np.nan, axis=0)


# -- mission time ---------------------------------------------------------------------------
class MissionClock:
    """Wall seconds since the flight started -> mission seconds, per vehicle and for
    the fleet (the median of the vehicles' clocks; past a vehicle's last report its
    clock is carried on at its own rate)."""

    def __init__(self, report: dict):
        self._per = {}
        starts = []
        for v in report.get("vehicles", []):
            t = np.asarray(v.get("track") or [], float)
            if t.ndim != 2 or t.shape[0] < 2 or t.shape[1] < 5:
                continue
            wall, boot = t[:, 0], t[:, 4]
            keep = np.concatenate([[True], np.diff(wall) > 0])
            wall, boot = wall[keep], boot[keep]
            if len(wall) < 2:
                continue
            rates = np.diff(boot) / np.diff(wall)
            rate = float(np.median(rates[np.isfinite(rates)])) if len(rates) else 1.0
            self._per[v["sysid"]] = (wall, boot, max(rate, 1e-6))
            starts.append(wall[0])
        self.mission = bool(self._per)
        self._t0 = min(starts) if starts else 0.0
        rates = [r for _, _, r in self._per.values()]
        self.rate = float(np.median(rates)) if rates else 1.0
        # each vehicle's clock, shifted so that all read the same at the first report
        self._offset = {s: boot[0] - (wall[0] - self._t0) * rate
                        for s, (wall, boot, rate) in self._per.items()}

    @property
    def label(self) -> str:
        return "mission time (s, vehicle clocks)" if self.mission else "wall time (s)"

    def vehicle(self, sysid, wall_s):
        """Mission time of ``wall_s`` on vehicle ``sysid``'s clock (the fleet's if none)."""
        if sysid not in self._per:
            return self.fleet(wall_s)
        wall, boot, rate = self._per[sysid]
        w = np.asarray(wall_s, float)
        inside = np.interp(w, wall, boot)
        out = np.where(w < wall[0], boot[0] + (w - wall[0]) * rate,
                       np.where(w > wall[-1], boot[-1] + (w - wall[-1]) * rate, inside))
        return out - self._offset[sysid]

    def fleet(self, wall_s):
        """Mission time of ``wall_s`` for events of no one vehicle (re-plans, losses)."""
        if not self._per:
            return np.asarray(wall_s, float)
        return np.median([self.vehicle(s, wall_s) for s in self._per], axis=0)

    def track_time(self, v) -> np.ndarray:
        """The mission time of each of a vehicle's track samples."""
        t = np.asarray(v["track"], float)
        if t.shape[1] >= 5 and v["sysid"] in self._per:
            return t[:, 4] - self._offset[v["sysid"]]
        return self.vehicle(v["sysid"], t[:, 0])


# -- the picture ----------------------------------------------------------------------------
#: inches at the top of flight.png for its title and the timeline's legend
TITLE_ROOM_IN = 1.6


def flight_png(path, terrain, surface, plan, report: dict) -> None:
    """The map (recorded tracks solid, planned routes faint, re-planned routes
    dashed, snapshots taken, losses), the timeline and the altitude profiles."""
    save_figure(flight_figure(terrain, surface, plan, report), path)


def flight_figure(terrain, surface, plan, report: dict):
    vehicles = report["vehicles"]
    clock = MissionClock(report)
    n = max(len(vehicles), 1)
    height = max(9.5, 2.0 + 1.9 * (n + 1)) + TITLE_ROOM_IN
    fig = plt.figure(figsize=(17, height), dpi=100)
    # the title's two lines and the timeline's legend above its panel get room of
    # their own at the top (the legend stood on the title)
    grid = fig.add_gridspec(n + 1, 2, width_ratios=[1.05, 1], height_ratios=[1.3] + [1] * n,
                            wspace=0.12, hspace=0.45, top=1.0 - TITLE_ROOM_IN / height)
    ax = fig.add_subplot(grid[:, 0])
    im = draw_background(ax, terrain, surface)
    draw_flight_map(ax, terrain, surface, plan, report, clock)
    fig.colorbar(im, ax=ax, shrink=0.5, pad=0.02,
                 label="hidden ceiling above ground (m): room to fly unseen")
    timeline = fig.add_subplot(grid[0, 1])
    draw_timeline(timeline, report, clock)
    first = None
    for i, v in enumerate(vehicles):
        pax = fig.add_subplot(grid[i + 1, 1], sharex=timeline if first is None else first)
        first = first or pax
        draw_altitude_profile(pax, terrain, surface, v, clock, last=i == len(vehicles) - 1,
                              silent=any(unheard(u).any() for u in vehicles))
    fig.suptitle(_title(report, clock), fontsize=12, y=1.0 - 0.15 / height, va="top")
    return fig


def draw_flight_map(ax, terrain, surface, plan, report, clock) -> None:
    planned = {r.id: r for r in plan.vehicles}
    handles = []
    for v in report["vehicles"]:
        c = vehicle_colour(v["vehicle"])
        route = planned.get(v["vehicle"])
        if route is not None and route.waypoints:
            x, y = lonlat_km(terrain, [w.lon for w in route.waypoints],
                              [w.lat for w in route.waypoints])
            ax.plot(x, y, "-", color=c, linewidth=0.9, alpha=0.35, zorder=4)
        handles.append(_draw_track(ax, terrain, v, c, clock))
    for r in report["replans"]:
        for sysid, points in r["routes"].items():
            if not points:
                continue
            p = np.asarray(points, float)
            x, y = lonlat_km(terrain, p[:, 0], p[:, 1])
            c = _colour_of_sysid(report, int(sysid))
            ax.plot(x, y, "-", color="white", linewidth=3.2, alpha=0.8, zorder=6)
            ax.plot(x, y, linestyle=(0, (4, 2)), color=c, linewidth=1.8, zorder=7)
    draw_bases(ax, terrain, plan)
    area = draw_area(ax, terrain, plan)
    handles += [area] if area is not None else []
    handles += [Line2D([], [], color="grey", linewidth=0.9, alpha=0.5,
                       label="planned route (faint)"),
                Line2D([], [], color="grey", linewidth=1.8, linestyle=(0, (4, 2)),
                       label="re-planned route (dashed)"),
                Line2D([], [], linestyle="none", marker="X", color="grey", markersize=10,
                       markeredgecolor="black", label="where a vehicle was lost")]
    if any(unheard(v).any() for v in report["vehicles"]):
        handles.append(Line2D([], [], color="grey", linestyle=":", linewidth=1.0,
                              label="out of contact (dotted: last heard to heard again)"))
    handles += symbol_legend(surface, snapshots=True, base=True)
    ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.09), ncol=2,
              fontsize=8, framealpha=0.9)


def _colour_of_sysid(report, sysid):
    for v in report["vehicles"]:
        if v["sysid"] == sysid:
            return vehicle_colour(v["vehicle"])
    return "black"


def _draw_track(ax, terrain, v, c, clock):
    label = f"sysid {v['sysid']} (UAV {v['vehicle']}) flown: {v['state']}"
    handle = Line2D([], [], color=c, linewidth=2.0, label=label)
    if v["track"]:
        t = np.asarray(v["track"], float)
        x, y = lonlat_km(terrain, t[:, 1], t[:, 2])
        gap = unheard(v)
        ax.plot(broken(x, gap), broken(y, gap), "-", color=c, linewidth=2.0, zorder=5)
        for k in np.flatnonzero(gap):        # where it went unheard and where heard again
            ax.plot(x[k:k + 2], y[k:k + 2], ":", color=c, linewidth=1.0, zorder=5)
        if v["state"] == "lost":
            ax.plot(x[-1], y[-1], "X", color=c, markersize=14, markeredgecolor="black",
                    zorder=11)
            last = float(clock.track_time(v)[-1])
            detected = f" (detected {float(clock.fleet(v['lost_at_s'])):.0f} s)" \
                if v.get("lost_at_s") is not None else ""
            ax.annotate(f"UAV {v['vehicle']} lost at {last:.0f} s\nmission time{detected}",
                        (x[-1], y[-1]),
                        fontsize=8, xytext=(8, 6), textcoords="offset points", zorder=11,
                        bbox=dict(boxstyle="round,pad=0.15", fc="white", ec=c, alpha=0.85))
    if v["snapshots"]:
        s = v["snapshots"]
        x, y = lonlat_km(terrain, [p["lon"] for p in s], [p["lat"] for p in s])
        ax.plot(x, y, "o", color=c, markersize=4, markeredgecolor="black",
                markeredgewidth=0.5, alpha=0.4 if v["state"] == "lost" else 1.0, zorder=8)
    return handle


def draw_timeline(ax, report, clock) -> None:
    """One row per vehicle: waiting for its takeoff time (dotted), flown (line),
    held by the separation guard (orange), snapshots (ticks), loss (X), landing
    (square); re-plans as shaded spans across every row."""
    vehicles = report["vehicles"]
    rows = {v["sysid"]: len(vehicles) - 1 - row for row, v in enumerate(vehicles)}
    for sysid, (t0, t1) in _ground_waits(report):
        a, b = (float(clock.vehicle(sysid, t)) for t in (t0, t1))
        ax.plot([a, b], [rows[sysid]] * 2, ":", color="black", linewidth=1.4, zorder=3)
    for sysid, (t0, t1) in _guard_holds(report):
        a, b = (float(clock.vehicle(sysid, t)) for t in (t0, t1))
        ax.broken_barh([(a, max(b - a, 1e-3))], (rows[sysid] - 0.18, 0.36),
                       facecolors=GUARD_COLOUR, edgecolors="black", hatch="////",
                       linewidth=0.6, zorder=4)
    for n, r in enumerate(report["replans"], start=1):
        t0 = float(clock.fleet(r["t_s"]))
        t1 = float(clock.fleet(r["done_t_s"])) if r.get("done_t_s") is not None else t0
        ax.axvspan(t0, max(t1, t0 + 1e-3), color=REPLAN_SHADE, alpha=0.6, zorder=1)
        ax.axvline(t0, color="black", linewidth=0.8, linestyle=":", zorder=2)
        ax.text(t0, len(vehicles) - 0.45, f" re-plan {n}", fontsize=8, va="bottom", zorder=5)
    for row, v in enumerate(vehicles):
        y = len(vehicles) - 1 - row
        c = vehicle_colour(v["vehicle"])
        spans = [[float(x) for x in clock.vehicle(v["sysid"], span)]
                 for span in _airborne(report, v["sysid"])]
        if spans and v["state"] == "lost" and v["track"]:    # to its last report
            spans[-1][1] = min(spans[-1][1], float(clock.track_time(v)[-1]))
        for a, b in spans:
            ax.plot([a, b], [y, y], "-", color=c, linewidth=5, alpha=0.55,
                    solid_capstyle="butt", zorder=3)
        for (_, a), (b, _) in zip(spans, spans[1:]):    # down between two sorties
            ax.plot([a, b], [y, y], "-", color=c, linewidth=1.5, alpha=0.8, zorder=3)
        if v["snapshots"]:
            ts = clock.vehicle(v["sysid"], [s["t_s"] for s in v["snapshots"]])
            ax.plot(ts, np.full(len(ts), y), "|", color="black", markersize=11,
                    markeredgewidth=1.2, zorder=4)
        if v["state"] == "lost" and v.get("lost_at_s") is not None:
            last = clock.track_time(v)[-1] if v["track"] else clock.fleet(v["lost_at_s"])
            ax.plot([last], [y], "X", color=c, markersize=13, markeredgecolor="black",
                    zorder=6)
            detected = float(clock.fleet(v["lost_at_s"]))
            ax.annotate(f"lost at {float(last):.0f} s (detected {detected:.0f} s)", (last, y),
                        xytext=(8, 5),
                        textcoords="offset points", fontsize=8, zorder=6)
        if v["state"] == "landed" and v.get("landed_at_s") is not None:
            ax.plot([clock.vehicle(v["sysid"], v["landed_at_s"])], [y], "s", color="white",
                    markeredgecolor="black", markersize=8, zorder=6)
    ax.set_yticks(range(len(vehicles)))
    ax.set_yticklabels([f"sysid {v['sysid']}\nUAV {v['vehicle']}" for v in reversed(vehicles)],
                       fontsize=8)
    ax.set_ylim(-0.7, len(vehicles) - 0.1)
    ax.set_xlabel(clock.label, fontsize=8)
    ax.tick_params(axis="x", labelsize=8)
    ax.grid(axis="x", alpha=0.3)
    ax.set_title("timeline", fontsize=10, loc="left")
    handles = [Line2D([], [], color="grey", linewidth=5, alpha=0.55, label="flying"),
               Line2D([], [], color="grey", linewidth=1.5, alpha=0.8,
                      label="on the ground between sorties (battery swap)"),
               Line2D([], [], linestyle="none", marker="|", color="black", markersize=10,
                      label="snapshot taken"),
               Line2D([], [], linestyle="none", marker="X", color="grey",
                      markeredgecolor="black", markersize=9, label="lost (last report)"),
               Line2D([], [], linestyle="none", marker="s", color="white",
                      markeredgecolor="black", markersize=7, label="landed"),
               plt.Rectangle((0, 0), 1, 1, color=REPLAN_SHADE, alpha=0.6,
                             label="re-planning (survivors held)"),
               Line2D([], [], linestyle=":", color="black", linewidth=1.4,
                      label="on the ground, waiting for its takeoff time"),
               Patch(facecolor=GUARD_COLOUR, edgecolor="black", hatch="////",
                     label="held by the separation guard")]
    ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, 1.42), ncol=4,
              fontsize=7.5, framealpha=0.9)


def _airborne(report, sysid) -> list:
    """[(from, to)] wall s of each flight of ``sysid``: from its takeoff (sent up,
    or seen flying in reports older than that event) to its landing or loss."""
    spans, up = [], None
    for e in report.get("events", []):
        if e.get("sysid") != sysid:
            continue
        if e["event"] in ("taking off", "flying") and up is None:
            up = e["t_s"]
        elif e["event"] in ("landed", "lost") and up is not None:
            spans.append((up, e["t_s"]))
            up = None
    if up is not None:
        spans.append((up, report.get("duration_s", up)))
    return spans


def _ground_waits(report) -> list:
    """[(sysid, (from, to))] wall s each vehicle stood waiting for its takeoff: from
    the first takeoff of the fleet to its own."""
    starts = {}
    for e in report.get("events", []):
        if e["event"] == "starting" and e.get("sysid") is not None:
            starts.setdefault(e["sysid"], e["t_s"])
    if not starts:
        return []
    first = min(starts.values())
    return [(s, (first, t)) for s, t in starts.items() if t > first]


def _guard_holds(report) -> list:
    """[(sysid, (from, to))] wall s of each hold by the separation guard."""
    return hold_spans(report.get("separation", {}).get("actions", []),
                      report.get("duration_s", 0.0))


def draw_altitude_profile(ax, terrain, surface, v, clock, last=False, silent=False) -> None:
    """A vehicle's altitude (AMSL) over mission time, the ground under it (the plan's
    ground for clearance, so the gap shown is the clearance it is guaranteed) and the
    hidden ceiling above it (NaN where the point is not in the flyable region); its
    silences shaded, no line through them (`unheard`). ``silent``: some vehicle has
    one, and the legend (under the ``last`` panel) says what the shade is."""
    c = vehicle_colour(v["vehicle"])
    ax.set_title(f"sysid {v['sysid']} (UAV {v['vehicle']}): altitude, metres AMSL",
                 fontsize=9, loc="left")
    if not v["track"]:
        ax.text(0.5, 0.5, "no position reports", transform=ax.transAxes, ha="center")
        return
    t = np.asarray(v["track"], float)
    tt = clock.track_time(v)
    x, y = terrain.from_lonlat(t[:, 1], t[:, 2])
    row, col = terrain.rowcol(x, y)
    ground = bilinear(terrain.upper, row, col)   # the ground its clearance is kept from
    ceiling = bilinear(surface.ceiling, row, col)
    bottom = np.nanmin(ground) - 30 if np.isfinite(ground).any() else np.nanmin(t[:, 3]) - 30
    gap = unheard(v)
    for k in np.flatnonzero(gap):
        ax.axvspan(tt[k], tt[k + 1], color=SILENT_SHADE, alpha=0.35, linewidth=0)
    ax.fill_between(broken(tt, gap), bottom, broken(ground, gap), color=TERRAIN_FILL,
                    alpha=0.6, linewidth=0,
                    label="ground under it (for clearance: nowhere below the DEM)")
    ax.plot(broken(tt, gap), broken(ceiling, gap), "--", color=CEILING_LINE, linewidth=1.0,
            label="hidden ceiling there (fly below)")
    ax.plot(broken(tt, gap), broken(t[:, 3], gap), "-", color=c, linewidth=1.6,
            label="flown altitude")
    if v["state"] == "lost":
        ax.plot(tt[-1], t[-1, 3], "X", color=c, markersize=10, markeredgecolor="black")
    ax.set_ylim(bottom, np.nanmax([np.nanmax(t[:, 3]), np.nanmax(ceiling) if np.isfinite(
        ceiling).any() else np.nan]) + 30)
    ax.tick_params(labelsize=7)
    ax.grid(alpha=0.3)
    ax.set_ylabel("m AMSL", fontsize=8)
    if last:
        # one legend for every panel, under the last: on a panel it covered its top,
        # where a flight comes closest to the ceiling
        ax.set_xlabel(clock.label, fontsize=8)
        handles, labels = ax.get_legend_handles_labels()
        # the flown line in no one vehicle's colour: the legend is every panel's
        handles = [Line2D([], [], color="grey", linewidth=1.6) if label == "flown altitude"
                   else h for h, label in zip(handles, labels)]
        if silent:                      # some vehicle's panel shades a silence
            handles.append(Patch(color=SILENT_SHADE, alpha=0.35))
            labels.append(SILENT_LABEL)
        ax.legend(handles, labels, loc="upper center", bbox_to_anchor=(0.5, -0.42),
                  fontsize=7.5, ncol=3, framealpha=0.9)


def _title(report, clock) -> str:
    cov = report.get("coverage", {}).get("survivors")
    losses = len(report["losses"])
    text = f"flight: {len(report['vehicles'])} vehicles, {losses} lost, " \
           f"{len(report['replans'])} re-plan(s)"
    if clock.mission:
        text += f"; mission time ran {clock.rate:.3g} × the wall clock"
    if cov:
        text += (f"\nk = {cov['k']}: {cov['k_covered']} of {cov['targets']} targets seen by "
                 f"{cov['required_uavs']} surviving vehicle(s) "
                 f"({100 * cov['fraction_k_covered']:.1f} %)")
    return text


__all__ = ["MissionClock", "flight_figure", "flight_png"]
