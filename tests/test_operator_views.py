"""What an operator reads (issue 23): maps with a legend entry for every symbol,
named outposts, a graticule, scale bar and north arrow; the 3-D view's colour bar
and vertical exaggeration; flight.png on mission time with a timeline and
altitude profiles; altitude frames; one palette in PNG, KML and GeoJSON; one
connect timeout. The plan is tests/conftest.py's."""

import argparse
import json
import math
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from matplotlib.colors import to_hex

from common.colours import OUTPOST_COLOUR, VEHICLE_COLOURS, kml_colour, vehicle_colour
from gcs.flight_plot import MissionClock, flight_figure
from gcs.plots import north_angle, overview_figure, view3d_figure
from missions.geo import routes_geojson, routes_kml

pytestmark = pytest.mark.timeout(120)


def _texts(fig) -> list:
    out = []
    for ax in fig.axes:
        out += [t.get_text() for t in ax.texts]
        legend = ax.get_legend()
        if legend is not None:
            out += [t.get_text() for t in legend.get_texts()]
        out += [ax.get_title(loc=where) for where in ("left", "center", "right")]
        out += [ax.get_xlabel(), ax.get_ylabel()]
    if fig._suptitle is not None:
        out.append(fig._suptitle.get_text())
    return out


def _legend(fig) -> list:
    return [t.get_text() for ax in fig.axes if ax.get_legend() is not None
            for t in ax.get_legend().get_texts()]


def test_overview_explains_every_symbol(planned):
    ctx, plan = planned.ctx, planned.plan
    fig = overview_figure(ctx.terrain, ctx.surface, plan)
    legend, texts = _legend(fig), _texts(fig)
    for needed in ("snapshot", "base", "outpost (named)", "outpost detection range",
                   "grey: no hidden room"):
        assert any(needed in t for t in legend), (needed, legend)
    for v in plan.vehicles:      # each with its takeoff time on the fleet clock
        assert any(t.startswith(f"UAV {v.id}: takeoff at {v.takeoff_s:.0f} s") for t in legend)
    # the post is named beside it with its range (its circle, wherever it crosses the
    # map, is labelled "hill: 2.5 km range"; here it lies outside the 1.8 km map)
    assert any(t.startswith("hill (2.5 km range)") for t in texts), texts
    # latitude / longitude labels, a scale bar and a north arrow
    assert any(t.endswith(("°N", "°S")) for t in texts) and \
        any(t.endswith(("°E", "°W")) for t in texts), texts
    assert any(t.endswith(" km") or t.endswith(" m") for t in texts)
    assert "N" in texts


def test_graticule_labels_are_where_those_coordinates_are(planned):
    """A longitude label on the bottom edge stands where that meridian crosses it."""
    ctx = planned.ctx
    fig = overview_figure(ctx.terrain, ctx.surface, planned.plan)
    ax = fig.axes[0]
    checked = 0
    for t in ax.texts:
        text = t.get_text()
        if text.endswith(("°E", "°W")):
            x, y = t.get_position()
            value = float(text[:-2]) * (-1 if text.endswith("W") else 1)
            from gcs.plots import _from_km
            lon, _ = ctx.terrain.to_lonlat(*_from_km(ctx.terrain, x, y))
            assert abs(lon - value) < 1e-6
            checked += 1
    assert checked >= 1


def test_north_arrow_is_true_north(planned):
    """On a UTM grid true north leans from grid north by the meridian convergence:
    east of the central meridian it leans west (counter-clockwise: a positive angle)."""
    t = planned.ctx.terrain
    a = north_angle(t)
    lon, lat = t.to_lonlat(*t.xy(t.shape[0] / 2, t.shape[1] / 2))
    zone_meridian = -183 + 6 * (int((lon + 180) // 6) + 1)
    expected = math.atan(math.tan(math.radians(lon - zone_meridian)) * math.sin(
        math.radians(lat)))
    assert a == pytest.approx(expected, abs=2e-3)


def test_view3d_has_colour_bar_and_states_exaggeration(planned):
    ctx = planned.ctx
    fig = view3d_figure(ctx.terrain, ctx.surface, planned.plan)
    assert len(fig.axes) == 2                             # the 3-D view and its colour bar
    assert "terrain altitude AMSL (m)" in fig.axes[1].get_ylabel()
    title = fig.axes[0].get_title()
    assert "vertical exaggeration ×" in title
    legend = _legend(fig)
    assert {"hidden ceiling (mesh)", "outpost", "base"} <= set(legend)


def _report(planned, rate=10.0):
    """A flight report as gcs fly writes it: vehicle clocks running ``rate`` times
    the wall clock, vehicle 2 lost at wall 6 s (last report at 4 s)."""
    plan = planned.plan
    vehicles = []
    for sysid, route in enumerate(plan.vehicles, start=1):
        w = route.waypoints
        end = 10 if sysid != 2 else 4
        walls = np.linspace(0.5, end, 20)
        pts = [w[min(int(i / 20 * len(w)), len(w) - 1)] for i in range(20)]
        track = [[float(t), p.lon, p.lat, p.alt_amsl, 100.0 + sysid + rate * float(t)]
                 for t, p in zip(walls, pts)]
        snaps = [{"t_s": 2.0, "lon": pts[5].lon, "lat": pts[5].lat, "alt_amsl": pts[5].alt_amsl,
                  "mission": 0, "waypoint": 5}]
        vehicles.append({"sysid": sysid, "vehicle": route.id, "flavour": "ardupilot",
                         "state": "lost" if sysid == 2 else "landed", "missions": 1,
                         "lost_at_s": 6.0 if sysid == 2 else None, "lost_reason": "silent",
                         "landed_at_s": None if sysid == 2 else 10.0, "snapshots": snaps,
                         "camera": [], "track": track})
    replans = [{"t_s": 6.5, "done_t_s": 7.0, "routes": {"1": [[p[1], p[2], p[3]] for p in
                                                               vehicles[0]["track"][10:]]}}]
    return {"vehicles": vehicles, "losses": [{"sysid": 2}], "replans": replans,
            "coverage": {}}


def test_mission_clock_runs_on_vehicle_time(planned):
    clock = MissionClock(_report(planned, rate=10.0))
    assert clock.mission and clock.rate == pytest.approx(10.0)
    assert clock.fleet(0.5) == pytest.approx(0.0, abs=1e-6)
    assert clock.fleet(6.0) == pytest.approx(55.0, abs=1e-6)   # past vehicle 2's clock too
    old = MissionClock({"vehicles": [{"sysid": 1, "track": [[0, 0, 0, 0], [1, 0, 0, 0]]}]})
    assert not old.mission and old.label == "wall time (s)"


def test_flight_figure_on_mission_time_with_timeline_and_profiles(planned):
    ctx = planned.ctx
    fig = flight_figure(ctx.terrain, ctx.surface, planned.plan, _report(planned))
    texts = _texts(fig)
    # mission time, not wall time: lost at 35 s (its last report), detected at 55 s
    assert any("lost at 35 s" in t and "detected 55 s" in t for t in texts), texts
    assert any(t == "mission time (s, vehicle clocks)" for t in texts)
    assert any("10 × the wall clock" in t for t in texts)
    assert any(t == "timeline" for t in texts)
    assert any(" re-plan 1" == t for t in texts)
    profiles = [t for t in texts if t.endswith("altitude, metres AMSL")]
    assert len(profiles) == len(planned.plan.vehicles)
    legend = _legend(fig)
    for needed in ("ground under it (for clearance: nowhere below the DEM)",
                   "hidden ceiling there (fly below)", "flown altitude",
                   "snapshot taken", "re-planning (survivors held)", "re-planned route (dashed)",
                   "planned route (faint)", "base: launch and landing point"):
        assert needed in legend, needed


def test_flight_figure_legends_cover_no_panel_and_not_the_title(planned):
    """flight.png's legends stand beside the panels, by their drawn extents: the
    altitude legends covered the top of each profile (where a flight comes closest
    to the ceiling), and the timeline's legend stood on the title."""
    ctx = planned.ctx
    fig = flight_figure(ctx.terrain, ctx.surface, planned.plan, _report(planned))
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    legends = [ax.get_legend() for ax in fig.axes if ax.get_legend() is not None]
    assert len(legends) >= 3                    # the map's, the timeline's, the profiles'
    panels = [ax.get_window_extent(renderer) for ax in fig.axes if ax.get_label() != "<colorbar>"]
    title = fig._suptitle.get_window_extent(renderer)
    for legend in legends:
        box = legend.get_window_extent(renderer)
        for panel in panels:
            assert not box.overlaps(panel), (legend.get_texts()[0].get_text(), panel)
        assert not box.overlaps(title), legend.get_texts()[0].get_text()


def test_flight_figure_draws_no_path_through_a_silence(planned):
    """Vehicle 1 unheard from wall 3 s to 6 s (its out_of_contact): no line on the map
    or on its altitude panel joins the last report before to the first after as if
    flown (a 15-min shadow was drawn as a straight flight through a valley); the map
    joins them dotted, the panel shades the silence over its 10x mission time, and
    each legend says so. A flight with no silence has neither."""
    from matplotlib.patches import Rectangle

    from gcs.flight_plot import SILENT_LABEL

    ctx = planned.ctx
    plain = _report(planned)
    report = _report(planned)
    one = report["vehicles"][0]
    walls = np.array([p[0] for p in one["track"]])
    before, after = walls[walls <= 3.0].max(), walls[walls >= 6.0].min()
    one["track"] = [p for p in one["track"] if not 3.0 < p[0] < 6.0]
    # marked over by the loop a moment after its first report (as in the demo's flight)
    one["out_of_contact"] = [{"from_s": float(before), "to_s": float(after) + 0.3,
                              "due_s": 9.0}]
    k = int(np.flatnonzero(np.array([p[0] for p in one["track"]]) == before)[0])
    colour = to_hex(vehicle_colour(one["vehicle"]))

    fig = flight_figure(ctx.terrain, ctx.surface, planned.plan, report)
    solid = [ln for ln in fig.axes[0].lines if to_hex(ln.get_color()) == colour
             and ln.get_linestyle() == "-" and ln.get_linewidth() == 2.0]
    [track] = [ln for ln in solid if len(ln.get_xdata()) == len(one["track"]) + 1]
    x = np.asarray(track.get_xdata(), float)
    assert np.flatnonzero(np.isnan(x)).tolist() == [k + 1]
    assert any(ln.get_linestyle() == ":" and to_hex(ln.get_color()) == colour
               and len(ln.get_xdata()) == 2 for ln in fig.axes[0].lines)
    panel = next(ax for ax in fig.axes if ax.get_title(loc="left").startswith("sysid 1 "))
    [flown] = [ln for ln in panel.lines if ln.get_label() == "flown altitude"]
    assert np.isnan(np.asarray(flown.get_ydata(), float)).sum() == 1
    # axvspan's shade: a Rectangle (matplotlib >= 3.9) or a Polygon
    widths = [r.get_width() if isinstance(r, Rectangle) else np.ptp(np.asarray(r.get_xy())[:, 0])
              for r in panel.patches]
    assert any(w == pytest.approx(10.0 * (after - before)) for w in widths), widths
    assert SILENT_LABEL in _legend(fig)
    assert SILENT_LABEL not in _legend(flight_figure(ctx.terrain, ctx.surface, planned.plan,
                                                     plain))


def test_one_palette_in_png_kml_and_geojson(planned):
    """UAV n has one colour everywhere; no vehicle is red, the outposts' colour."""
    ctx, plan = planned.ctx, planned.plan
    assert OUTPOST_COLOUR not in VEHICLE_COLOURS
    assert len({vehicle_colour(i) for i in range(1, 17)}) == 16  # a 16-UAV fleet repeats none
    fig = overview_figure(ctx.terrain, ctx.surface, plan)
    png = {line.get_label(): to_hex(line.get_color()) for line in fig.axes[0].lines}
    doc = routes_geojson(plan)
    kml = ET.fromstring(routes_kml(plan))
    ns = {"k": "http://www.opengis.net/kml/2.2"}
    styles = {s.get("id"): s.find("k:LineStyle/k:color", ns).text
              for s in kml.findall(".//k:Style", ns)}
    for v in plan.vehicles:
        colour = vehicle_colour(v.id)
        assert any(label.startswith(f"UAV {v.id}: takeoff") and c == colour
                   for label, c in png.items()), png
        route = next(f for f in doc["features"] if f["properties"]["kind"] == "route"
                     and f["properties"]["vehicle"] == v.id)
        assert route["properties"]["stroke"] == colour
        mark = next(p for p in kml.iter("{http://www.opengis.net/kml/2.2}Placemark")
                    if p.find("k:name", ns).text == f"vehicle {v.id} route")
        style = mark.find("k:styleUrl", ns).text.lstrip("#")
        assert styles[style] == kml_colour(colour)
    outpost = next(f for f in doc["features"] if f["properties"]["kind"] == "outpost")
    assert outpost["properties"]["marker-color"] == OUTPOST_COLOUR
    assert styles["outpost"] == kml_colour(OUTPOST_COLOUR)
    assert kml_colour("#1f77b4") == "ffb4771f"
    json.dumps(doc, allow_nan=False)


def test_live_table_says_alt_is_above_home():
    from gcs.cli.views import status_table

    table = status_table([{"sysid": 1, "vehicle": 1, "mode": "AUTO", "item": "3/9",
                           "mission": 0, "snapshots": "1 (1/4)", "alt": -129.0,
                           "heartbeat_s": 0.2, "battery": 90, "state": "flying"}])
    headers = [c.header for c in table.columns]
    assert "alt above home" in headers and "alt" not in headers


def test_one_connect_timeout_for_upload_download_and_fly():
    from gcs.cli import download, fly, upload
    from gcs.cli.options import CONNECT_TIMEOUT_S
    from gcs.flight import FlyOptions

    defaults = set()
    for module in (upload, download, fly):
        parser = argparse.ArgumentParser()
        module.add_arguments(parser)
        defaults.add(parser.get_default("connect_timeout"))
    assert defaults == {CONNECT_TIMEOUT_S}
    assert FlyOptions().connect_timeout_s == CONNECT_TIMEOUT_S


@pytest.mark.parametrize("outposts", [0, 2])
def test_the_flight_summary_says_what_of_the_area_its_targets_are(planned, capsys, outposts):
    """"100 % of targets" is of the plan's targets: the flight's summary says what
    of the area of operations they are, and that nothing was hidden from anyone
    when the plan has no observers."""
    from gcs.cli.views import summary

    report = {"losses": [], "replans": [], "duration_s": 60.0, "k": 1,
              "area": planned.plan.metrics["area"], "outposts": outposts,
              "coverage": {"survivors": {"k": 1, "k_covered": 10, "targets": 10,
                                         "required_uavs": 2, "fraction_k_covered": 1.0}},
              "outcome": {"ok": True, "problems": []}}
    summary(report)
    out = capsys.readouterr()
    text = " ".join((out.out + out.err).split())
    a = planned.plan.metrics["area"]
    assert f"plan: area of operations {a['area_km2']:.2f} km²" in text
    assert f"{a['planned']['km2']:.2f} km²" in text
    assert ("plan: no observers: planned with no outposts" in text) == (outposts == 0)


def test_a_piped_flight_prints_a_progress_line_every_so_often(monkeypatch):
    """With output not a terminal, the status table is one line every `PROGRESS_S`
    wall seconds (the flight was silent for minutes between takeoff and landing)."""
    from gcs.cli import views

    now = [100.0]
    monkeypatch.setattr(views.time, "monotonic", lambda: now[0])
    lines = []
    status = views.progress_lines(lines.append, every_s=15.0)
    row = {"sysid": 2, "state": "flying", "item": "7/40", "snapshots": "3 (3/12)",
           "battery": 81}
    for t in (100.0, 105.0, 114.9, 115.0, 129.0, 130.0):
        now[0] = t
        status([row])
    assert lines == ["progress: vehicle 2 flying, item 7/40, snapshots 3 (3/12), battery 81 %"] * 3


def test_flight_figure_draws_the_area_polygon(planned, tmp_path):
    """flight.png draws the plan's --area-file polygon, as overview.png does."""
    from dataclasses import replace

    ctx = planned.ctx
    rows, cols = ctx.terrain.shape
    corners = [ctx.terrain.to_lonlat(*ctx.terrain.xy(r, c))
               for r, c in ((5, 5), (5, cols - 6), (rows - 6, cols - 6), (rows - 6, 5), (5, 5))]
    area = tmp_path / "area.geojson"
    area.write_text(json.dumps({"type": "Polygon", "coordinates": [
        [[float(lon), float(lat)] for lon, lat in corners]]}))
    plan = replace(planned.plan, params={**planned.plan.params, "area_file": str(area)})
    fig = flight_figure(ctx.terrain, ctx.surface, plan, _report(planned))
    assert "area of operations (targets inside)" in _legend(fig)


@pytest.mark.parametrize("figure", ["overview", "flight"])
def test_maps_draw_the_area_box_where_its_corners_are(planned, figure):
    """The --area box is the area of operations too (targets and flight stay inside;
    the DEM is read wider around an outpost outside it, and the map with it):
    overview.png and flight.png draw it dashed, its corners at the cells given as its
    corners, placed from the grid's own geometry (cell centres from the south-west
    corner), not by the maps' projection."""
    from dataclasses import replace

    ctx = planned.ctx
    terrain = ctx.terrain
    rows, cols = terrain.shape
    (r0, c0), (r1, c1) = (rows - 6, 4), (5, cols - 8)      # south-west, north-east cells
    lon0, lat0 = terrain.to_lonlat(*terrain.xy(r0, c0))
    lon1, lat1 = terrain.to_lonlat(*terrain.xy(r1, c1))
    plan = replace(planned.plan, params={**planned.plan.params, "area_file": None,
                                         "area": [float(lat0), float(lon0), float(lat1),
                                                  float(lon1)]})
    fig = (overview_figure(terrain, ctx.surface, plan) if figure == "overview" else
           flight_figure(terrain, ctx.surface, plan, _report(planned)))
    assert "area of operations (targets and flight inside)" in _legend(fig)
    [line] = [ln for ln in fig.axes[0].lines
              if ln.get_label() == "area of operations (targets and flight inside)"]
    x, y = (np.asarray(v) for v in line.get_data())
    d = terrain.cell_size / 1000.0
    for r, c in ((r0, c0), (r1, c1)):
        corner = np.array([(c + 0.5) * d, (rows - r - 0.5) * d])
        assert np.hypot(x - corner[0], y - corner[1]).min() < 0.5 * d, (r, c)


def test_the_north_arrow_keeps_off_the_points_a_map_draws_on_top(planned):
    """A base standing where the arrow goes (upper left): the arrow stands elsewhere,
    clear of it (bases.png had base squares on the arrow); with nothing to avoid it
    stays in the upper left."""
    import matplotlib.pyplot as plt

    from gcs.plots import NORTH_CLEAR, NORTH_PLACES, draw_background

    ctx = planned.ctx

    def north(avoid):
        fig, ax = plt.subplots()
        draw_background(ax, ctx.terrain, ctx.surface, avoid=avoid)
        x0, x1 = ax.get_xlim()
        y0, y1 = ax.get_ylim()
        [n] = [t for t in ax.texts if t.get_text() == "N"]
        plt.close(fig)
        return np.array(n.get_position()), (x0, x1, y0, y1)

    alone, (x0, x1, y0, y1) = north(())
    fx, fy = NORTH_PLACES[0]
    upper_left = (x0 + fx * (x1 - x0), y0 + fy * (y1 - y0))
    assert math.dist(alone, upper_left) < 0.15 * (x1 - x0)
    moved, _ = north([upper_left])
    assert math.dist(moved, upper_left) > NORTH_CLEAR * min(x1 - x0, y1 - y0)


def test_a_range_label_keeps_off_the_bases(planned):
    """A range's label stands on its circle, elsewhere than where a base stands (in
    bases.png a base square hid "South summit: 8 km range"): the label's box, as wide
    as its text, holds no base. (Other posts' names are kept off the same way.)"""
    from types import SimpleNamespace

    import matplotlib.pyplot as plt

    from gcs.plots import LABEL_CHAR_SHARE, LABEL_CLEAR, LABEL_HEIGHT_SHARE, draw_background
    from planner.exposure import Outpost

    ctx = planned.ctx
    rows, cols = ctx.terrain.shape
    x, y = ctx.terrain.xy(rows // 2, cols // 2)
    post = Outpost(float(x), float(y), 2.0, 400.0, name="ring")
    surface = SimpleNamespace(ceiling=ctx.surface.ceiling, outposts=[post])
    text = "ring: 0.4 km range"

    def label(avoid):
        fig, ax = plt.subplots()
        draw_background(ax, ctx.terrain, surface, avoid=avoid)
        x0, x1 = ax.get_xlim()
        y0, y1 = ax.get_ylim()
        [t] = [t for t in ax.texts if t.get_text() == text]
        plt.close(fig)
        return np.array(t.xy), t.get_horizontalalignment(), (x0, x1, y0, y1)

    first, _, (x0, x1, y0, y1) = label(())
    moved, ha, _ = label([first])
    width = LABEL_CHAR_SHARE * len(text) * (x1 - x0)
    lo, hi = (moved[0] - width, moved[0]) if ha == "right" else (moved[0], moved[0] + width)
    near = LABEL_CLEAR * min(x1 - x0, y1 - y0)
    assert not (lo - near < first[0] < hi + near
                and moved[1] - near < first[1] < moved[1] + LABEL_HEIGHT_SHARE * (y1 - y0) + near)
    # still on its circle
    cx, cy = (x - ctx.terrain.transform.c) / 1000.0, \
        (y - (ctx.terrain.transform.f + rows * ctx.terrain.transform.e)) / 1000.0
    assert math.hypot(moved[0] - cx, moved[1] - cy) == pytest.approx(0.4, abs=1e-6)


def test_no_graticule_labels_in_the_lower_left_corner(planned):
    """The corner where a longitude label along the bottom and a latitude label up
    the left side collided keeps none."""
    from gcs.plots import GRATICULE_CORNER

    ctx = planned.ctx
    fig = overview_figure(ctx.terrain, ctx.surface, planned.plan)
    ax = fig.axes[0]
    x0, x1 = ax.get_xlim()
    y0, y1 = ax.get_ylim()
    labels = [t.get_position() for t in ax.texts if "°" in t.get_text()]
    assert labels
    assert not [(x, y) for x, y in labels if x < x0 + GRATICULE_CORNER * (x1 - x0)
                and y < y0 + GRATICULE_CORNER * (y1 - y0)]
