"""Outcomes told as they are: a touchdown away from launch, before the last item or
below the terrain is a crash (lost, snapshots lost); landed survivors go up again
when a loss leaves coverage short; `gcs fly` exits non-zero and says why; the
timeout and Ctrl-C ask (or bring everyone home); `gcs sim --terrain` stands on it.

Flights are judged by the simulated vehicles' own tracks (`gcs.sim.read_track`)
and the planner's sensor model on the snapshot positions they recorded.
"""

import io
import json
import threading
import time
from types import SimpleNamespace

import numpy as np
import pytest
from flown import problems_beside_guard
from rich.console import Console
from sim_fleet import quick_fleet

from common.errors import InputError
from gcs.cli import build_parser, main, views
from gcs.cli import sim as sim_cli
from gcs.monitor import LANDED, LOST, Monitor
from gcs.sim import SimFleet, free_base_port, read_track, track_path
from gcs.sim.fleet import terrain_ground
from missions.build import MissionOptions, vehicle_mission
from planner.replan import coverable_targets, coverage_summary

pytestmark = pytest.mark.timeout(150)


# -- the monitor's judgement, step by step ---------------------------------------------------
class _Link:
    """A vehicle as the monitor sees it: its state, and messages pushed to it."""

    def __init__(self, launch):
        self.sysid, self.flavour = 1, "ardupilot"
        self.state = SimpleNamespace(lat=launch[0], lon=launch[1], alt_amsl=launch[2],
                                     relative_alt=0.0, home=None, landed=None, mission_seq=None,
                                     armed=True, last_heartbeat=time.monotonic(), mode="AUTO",
                                     battery_pct=90)
        self.home_alt = launch[2]
        self.callbacks = []

    def subscribe(self, cb):
        self.callbacks.append(cb)
        return lambda: None

    def heartbeat_age(self):
        return time.monotonic() - self.state.last_heartbeat

    silent_s = heartbeat_age

    def at(self, lat, lon, alt, armed=True, seq=None):
        """A position report, then a heartbeat, from there."""
        s = self.state
        s.lat, s.lon, s.alt_amsl, s.relative_alt = lat, lon, alt, alt - self.home_alt
        s.armed, s.mission_seq = armed, seq if seq is not None else s.mission_seq
        s.last_heartbeat = time.monotonic()
        for msg in (SimpleNamespace(relative_alt=s.relative_alt * 1e3, lat=lat * 1e7,
                                    lon=lon * 1e7, alt=alt * 1e3,
                                    get_type=lambda: "GLOBAL_POSITION_INT"),
                    SimpleNamespace(base_mode=128 if armed else 0, get_type=lambda: "HEARTBEAT")):
            for cb in self.callbacks:
                cb(msg)


@pytest.fixture
def judged(planned):
    """(monitor, link, route, mission, ground(lat, lon)) for vehicle 1 of the plan."""
    route = planned.plan.vehicles[0]
    mission = vehicle_mission(route, "ardupilot", MissionOptions(speed_mps=12.0))
    ground = terrain_ground(planned.terrain)
    monitor = Monitor(5.0, ground=ground)
    link = _Link(planned.launch)
    monitor.follow(link, route.id, route, mission)
    return monitor, link, route, mission, ground


def _fly_out(link, route, ground, k):
    """Climb at launch, then over waypoint ``k`` at its planned altitude."""
    lat, lon, alt = route.launch.lat, route.launch.lon, route.launch.alt_amsl
    link.at(lat, lon, alt + 50.0, seq=2)
    w = route.waypoints[k]
    link.at(w.lat, w.lon, w.alt_amsl, seq=5)
    return w


def test_touchdown_away_from_launch_is_a_crash(judged):
    monitor, link, route, mission, ground = judged
    w = _fly_out(link, route, ground, len(route.waypoints) // 2)
    # flat SITL ground above this valley: touching it reads 0 m above home
    link.at(w.lat, w.lon, link.home_alt, armed=False)
    v = monitor.vehicles[1]
    assert v.state == LOST and "touched the ground" in v.lost_reason
    assert "from its base" in v.lost_reason
    assert monitor.check_losses() == [1]


def test_touchdown_at_launch_before_the_last_item_is_a_crash(judged):
    monitor, link, route, mission, ground = judged
    _fly_out(link, route, ground, 3)
    link.at(route.launch.lat, route.launch.lon, route.launch.alt_amsl, armed=False, seq=8)
    v = monitor.vehicles[1]
    assert v.state == LOST and "before its last item" in v.lost_reason


def test_below_the_terrain_is_a_crash_even_armed(judged):
    monitor, link, route, mission, ground = judged
    w = _fly_out(link, route, ground, len(route.waypoints) // 3)
    link.at(w.lat, w.lon, ground(w.lat, w.lon) + 1.0)      # 1 m above the DEM, still armed
    v = monitor.vehicles[1]
    assert v.state == LOST and "above the terrain" in v.lost_reason


def test_landing_at_launch_after_the_last_waypoint(judged):
    monitor, link, route, mission, ground = judged
    _fly_out(link, route, ground, 3)
    land = len(mission.items) - 1
    link.at(route.launch.lat, route.launch.lon, route.launch.alt_amsl + 40.0, seq=land)
    link.at(route.launch.lat + 2e-6, route.launch.lon, route.launch.alt_amsl, armed=False)
    assert monitor.vehicles[1].state == LANDED


# -- whole flights -----------------------------------------------------------------------------
def _flown(out, sysids):
    return {s: read_track(track_path(out / "tracks", s)) for s in sysids}


def test_flat_ground_above_the_valleys_is_a_loss_not_a_landing(planned, tmp_path):
    """The issue's flight: simulated copters on flat ground at the launch altitude (no
    --terrain) while the routes dip into valleys below it. A copter that hits that
    ground far from launch is lost, not "landed", and the exit status says so."""
    lows = [min(w.alt_amsl for w in r.waypoints) for r in planned.plan.vehicles]
    assert max(lows) < planned.launch[2]                   # every route goes below launch
    base = free_base_port(10, 3)
    out = tmp_path / "flight"
    fleet = quick_fleet(3, homes=[planned.launch] * 3, speedup=100.0, base_port=base,
                        track_dir=out / "tracks")
    try:
        code = main(["fly", str(planned.dir), *[a for i in range(3) for a in
                     ("--connect", f"tcp:127.0.0.1:{base + 10 * i}")],
                     "--lost-after", "2", "--timeout", "60", "--set-failsafes", "-o", str(out)])
    finally:
        fleet.stop()
    report = json.loads((out / "flight.json").read_text())
    assert code == 1 and not report["outcome"]["coverage_reached"]
    # the first copter to touch that ground is lost; what follows depends on timing
    # (the others lost the same way, re-tasked home, or a re-plan that cannot join
    # a vehicle lying below the terrain): each report must match what the
    # simulator saw, and a touchdown away from launch is never "landed"
    assert report["outcome"]["lost"]
    assert all("touched the ground" in loss["reason"] for loss in report["losses"])
    state = {v["sysid"]: v["state"] for v in report["vehicles"]}
    lat0, lon0 = np.radians(planned.launch[:2])
    for sysid, track in _flown(out, [1, 2, 3]).items():   # the simulator's own record
        far = 6371e3 * np.hypot(np.radians(track.lat[-1]) - lat0,
                                (np.radians(track.lon[-1]) - lon0) * np.cos(lat0))
        touched = any(e["event"] == "landed" for e in track.events)
        if touched and far > 100.0:
            assert state[sysid] == "lost", sysid
        if state[sysid] == "landed":
            assert touched and far < 3.0, sysid


def _shoot_when_the_others_landed(fleet, victim, shot: list, limit_s=60.0):
    """Kill ``victim`` as soon as every other vehicle has flown and is down again;
    ``shot`` gets True, or False when the victim was down first."""
    others = [v for v in fleet.vehicles if v.sysid != victim]
    flew = set()
    deadline = time.monotonic() + limit_s
    while time.monotonic() < deadline:
        flew |= {v.sysid for v in others if not v.landed}
        if len(flew) == len(others) and all(v.landed for v in others):
            shot.append(not fleet.vehicle(victim).landed)
            fleet.kill(victim)
            return
        time.sleep(0.01)


def test_readme_recipe_with_a_late_loss_relaunches_a_landed_vehicle(planned, tmp_path):
    """`gcs sim --home LAT,LON --terrain PLAN` (home altitude from the DEM), then `gcs fly
    PLAN --connect ...`. Vehicle 1 is shot down late, when the others have landed: its
    snapshots are lost, coverage is short, and the landed ones go up again."""
    base = free_base_port(10, 3)
    out = tmp_path / "flight"
    # the victim: the vehicle planned to land last, shot down once the others are down
    ends = {v.id: v.mission_time_s for v in planned.plan.vehicles}
    victim = max(ends, key=ends.get)
    lat, lon, _ = planned.launch
    args = build_parser().parse_args([
        "sim", "--vehicles", "3", "--home", f"{lat},{lon}", "--terrain", str(planned.dir),
        "--speedup", "100", "--base-port", str(base), "--warmup", "0.5",
        "--track-dir", str(out / "tracks")])
    config = sim_cli.config_from_args(args)
    assert config.home[2] == pytest.approx(planned.launch[2], abs=0.01)
    fleet = SimFleet(config)
    # the victim's clock runs at half speed: it is surely still up when the others
    # are down (planned mission times alone differ by a fraction of a wall second)
    fleet.vehicle(victim).cfg.speedup = 50
    fleet.start()
    shot = []
    shooter = threading.Thread(target=_shoot_when_the_others_landed, args=(fleet, victim, shot),
                               daemon=True)
    shooter.start()
    try:
        code = main(["fly", str(planned.dir), *[a for i in range(3) for a in
                     ("--connect", f"tcp:127.0.0.1:{base + 10 * i}")],
                     "--lost-after", "2", "--timeout", "90", "--set-failsafes", "-o", str(out)])
    finally:
        fleet.stop()
    report = json.loads((out / "flight.json").read_text())
    survivors = sorted(set(ends) - {victim})
    assert shot == [True], "the victim was down before the others"
    assert code == 1 and report["outcome"]["lost"] == [victim]
    assert report["outcome"]["coverage_reached"] and report["outcome"]["in_air"] == []
    relaunched = report["replans"][0]["relaunched"]
    assert relaunched and set(relaunched) <= set(survivors)
    tracks = _flown(out, [1, 2, 3])
    assert tracks[victim].killed_at is not None
    ctx = planned.ctx
    snaps = []
    for sysid in survivors:
        t = tracks[sysid]
        takeoffs = [e for e in t.events if e["event"] == "takeoff"]
        assert len(takeoffs) == (2 if sysid in relaunched else 1), sysid
        assert abs(t.alt[-1] - planned.launch[2]) < 1.0       # down at launch at the end
        s = np.array([[p["lon"], p["lat"], p["alt"]] for p in t.snapshots]).reshape(-1, 3)
        x, y = ctx.terrain.from_lonlat(s[:, 0], s[:, 1])
        snaps.append(np.stack([x, y, s[:, 2]], axis=1))
    cov = coverage_summary(ctx, snaps, ctx.scenario.k)
    assert cov["k_covered"] == coverable_targets(ctx)       # from what they really shot


def test_an_empty_battery_in_the_air_is_a_problem(planned, tmp_path):
    """The plan has no --endurance; its simulated copters carry batteries good for
    half the shortest mission (`gcs sim --battery`). Each runs empty in the air and
    flies on (the simulator's ArduPilot has its battery failsafe off): the outcome
    names every vehicle whose battery the simulator's own track saw run empty, no
    other, and `gcs fly` exits 1 (it said `landed battery_pct=0`, then "required
    coverage reached, no vehicle lost, all landed", exit 0)."""
    assert planned.plan.params.get("endurance_min") is None
    shortest = min(v.mission_time_s for v in planned.plan.vehicles)
    base = free_base_port(10, 3)
    out = tmp_path / "flight"
    lat, lon, _ = planned.launch
    args = build_parser().parse_args([
        "sim", "--vehicles", "3", "--home", f"{lat},{lon}", "--terrain", str(planned.dir),
        "--speedup", "100", "--base-port", str(base), "--warmup", "0.5",
        "--battery", f"{shortest / 120:.3f}", "--track-dir", str(out / "tracks")])
    fleet = SimFleet(sim_cli.config_from_args(args)).start()
    try:
        code = main(["fly", str(planned.dir), *[a for i in range(3) for a in
                     ("--connect", f"tcp:127.0.0.1:{base + 10 * i}")],
                     "--lost-after", "2", "--timeout", "90", "--set-failsafes", "-o", str(out)])
    finally:
        fleet.stop()
    report = json.loads((out / "flight.json").read_text())
    emptied = {s for s, t in _flown(out, [1, 2, 3]).items()
               if any(e["event"] == "battery empty" for e in t.events)}
    assert emptied == {1, 2, 3}
    assert code == 1 and not report["outcome"]["ok"]
    said = {s for s in (1, 2, 3) for p in report["outcome"]["problems"]
            if p.startswith(f"vehicle {s}'s battery reported empty in the air")}
    assert said == emptied, report["outcome"]["problems"]
    assert not [p for p in problems_beside_guard(report) if "battery" not in p]


def test_timeout_brings_everyone_home_when_nobody_can_be_asked(planned, tmp_path):
    out = tmp_path / "flight"
    code = main(["fly", str(planned.dir), "--sim", "3", "--speedup", "100", "--timeout", "1.5",
                 "--lost-after", "2", "--sim-base-port", str(free_base_port(10, 3)),
                 "-o", str(out)])
    report = json.loads((out / "flight.json").read_text())
    assert code == 1
    outcome = report["outcome"]
    assert outcome["timed_out"] and outcome["in_air"] == [] and outcome["lost"] == []
    assert any(e["event"] == "timed out after 1.5 s: home" for e in report["events"])
    for sysid, track in _flown(out, [1, 2, 3]).items():
        assert abs(track.alt[-1] - planned.launch[2]) < 1.0, sysid


# -- gcs sim --terrain, the Ctrl-C prompt ---------------------------------------------------
def test_sim_home_stands_on_the_terrain(planned, capsys):
    lat, lon, ground = planned.launch
    parser = build_parser()
    args = parser.parse_args(["sim", "--home", f"{lat},{lon}", "--terrain", str(planned.dir)])
    assert sim_cli.config_from_args(args).home == pytest.approx((lat, lon, ground), abs=1e-3)
    for alt in (ground + 5.0, ground - 0.4):          # in the air, or under the ground
        assert main(["sim", "--home", f"{lat},{lon},{alt}", "--terrain", str(planned.dir),
                     "--duration", "0"]) == 2
        err = capsys.readouterr().err.strip()
        assert err.startswith("gcs sim: error: --home: home altitude") and "ground" in err
        assert len(err.splitlines()) == 1
    with pytest.raises(InputError, match="outside the --terrain"):
        sim_cli.config_from_args(parser.parse_args(["sim", "--home", "10,10", "--terrain",
                                                    str(planned.dir)]))


def test_prompt_shows_its_choices_and_asks_again(monkeypatch):
    shown = io.StringIO()
    monkeypatch.setattr(views, "console", Console(file=shown, width=200))
    answers = iter(["", "maybe", "h"])
    monkeypatch.setattr("builtins.input", lambda *a: next(answers))
    view = SimpleNamespace(stop=lambda: None, start=lambda: None)
    assert views.ask(view, "interrupted") == "home"
    text = shown.getvalue()
    assert text.count("[h]ome / [l]eave them on their missions") == 3
    assert "not 'maybe'" in text
    answers = iter(["L"])
    assert views.ask(view, "timed out after 5 s") == "leave"
