"""Flying a plan: connect, upload, start, monitor, re-task on losses, report.

    report = fly(plan_dir, ["tcp:127.0.0.1:5760", ...], FlyOptions(output="flight"))

Stages (each in its own module): before any connection the plan is read and
every route's mission built for each autopilot (`missions.build`) and proven
hidden and clear against the plan's surface (`missions.check.checked`: only a
`CheckedMission` is uploaded); `gcs.link` finds the vehicles; each gets its
checked mission, uploaded with read-back (`gcs.mission_protocol.upload_verified`);
`gcs.commands.start_mission` takes off; `gcs.monitor` follows them and detects
losses (silence, a fall, a touchdown away from launch or before the last item,
flight below the terrain); `gcs.retask` re-plans the survivors. Missions fly
the fewest waypoints the leg proofs allow (`missions.segments.fewer_waypoints`);
a route longer than its vehicle holds (its capacity, learned at the first
upload) is flown in segments, the next uploaded in flight (`gcs.segments`). At the end
``flight.json`` and ``flight.png`` are written to the output directory, with
one ``.tlog`` per vehicle beside them.

Coverage at the end is re-evaluated from the snapshot positions with the
planner's own sensor model; a lost vehicle's snapshots count as lost. The
report's ``outcome`` says whether the flight did its job: the required
coverage reached, no vehicle lost, none left in the air.
"""

import json
import math
import threading
import time
from dataclasses import asdict, dataclass, field, replace
from datetime import datetime, timezone
from pathlib import Path
from types import SimpleNamespace

from autopilots import NAMES
from common.errors import InputError
from common.fileio import write_text_atomic
from gcs import commands
from gcs.clock import FleetClock
from gcs.guard import SeparationGuard
from gcs.link import GroundLink, LinkError
from gcs.mission_protocol import MissionError
from gcs.monitor import (
    FLYING,
    HOLDING,
    LANDED,
    LOST,
    MIN_LAUNCH_TOLERANCE_M,
    STARTING,
    STRANDED,
    SWAP_SILENCE_S,
    WAITING,
    Monitor,
    distance_m,
)
from gcs.retask import Retasker, RetaskError, _in_parallel, snapshot_xyz
from gcs.segments import Segments, upload_route
from missions.build import MissionOptions, vehicle_mission
from missions.check import checked
from missions.items import NAV_LAND
from missions.segments import RouteMissions, fewer_waypoints
from planner.fleet import prove_separated, stop_time
from planner.plan import PLAN_FILE, Plan
from planner.replan import LAUNCH_COLUMN_M, coverable_targets, coverage_summary
from planner.travel import leg_time

FORMAT = "gcs-flight/1"
FLIGHT_FILE = "flight.json"
PLOT_FILE = "flight.png"
TLOG_PATTERN = "vehicle_{sysid}.tlog"
#: the plan made from where the vehicles stand (``from_where_they_stand``), in the output
PLAN_FROM_HERE = "plan-from-where-they-stand"
LOOP_S = 0.1
#: after a timeout brought the vehicles home, wait at least this long (wall s) for them
HOME_WAIT_S = 60.0
#: a battery failsafe that does one of these stays hidden: straight down from a
#: hidden point is below the exposure surface (`check_failsafes`)
HIDDEN_FAILSAFES = ("a warning", "LAND where", "brake where")
#: m/s an autopilot's rate limit may fall short of the plan's (float32, unit rounding)
RATE_SLACK_MPS = 0.01
#: how far (m) a vehicle may stand from its launch point when the plan names no track
#: tolerance (plans older than it)
LAUNCH_TOLERANCE_M = 5.0
#: wall seconds a called-off start sequence is given to stop (its command in flight
#: answered or timed out)
CALL_OFF_WAIT_S = 10.0
#: a battery reporting this much (%) or more is fresh: the next sortie may go
FRESH_BATTERY_PCT = 95
#: fleet seconds of a sortie, and % of its battery drawn, before its rate of draw is
#: trusted by the battery watch
WATCH_AFTER_S, WATCH_AFTER_PCT = 120.0, 8
#: a battery drawn this many times faster than its rating (the plan's endurance) is
#: not trusted: the vehicle comes home early and stays down
FAST_DRAIN = 1.25
#: hover seconds of battery one metre of climb costs: lifting m g per metre on a hover
#: power P takes m g / P seconds of it (a 1.5 kg quadcopter hovering on 180 W: 0.08 s;
#: the simulator's battery draws so). A sortie's first minutes are mostly its takeoff
#: climb: judged by time alone, batteries drawing as rated read 1.4 times faster.
CLIMB_S_PER_M = 0.08
#: how near (m) a vehicle stands to a waypoint it holds at: there it spends the hold
#: its plan gives it (autopilots hold within their 2 m acceptance radius by default)
AT_WAYPOINT_M = 5.0


@dataclass
class SortieDraw:
    """What a vehicle's battery was at its liftoff, and the metres it has climbed since
    (from its position reports, `climbed`)."""
    t0: float                    # monitor s
    own0: float | None           # its own clock
    pct0: int | None             # charge
    index: int                   # its position reports counted into ``climbed`` so far
    alt: float | None            # the altitude of the last of them
    sortie: int = 1              # which of its route's sorties
    flight_s: float = 0.0        # the sortie's planned time, takeoff to landing
    climbed: float = 0.0         # m
    forecast: bool = False       # its landing charge said (`Flight._forecast`)

    def climb_to(self, track, until_own) -> float:
        """Metres climbed from liftoff to its own clock ``until_own``."""
        while self.index < len(track) and track[self.index][4] <= until_own:
            alt = track[self.index][3]
            if self.alt is not None:
                self.climbed += max(0.0, alt - self.alt)
            self.alt, self.index = alt, self.index + 1
        return self.climbed


@dataclass
class FlyOptions:
    output: Path | str = "flight"
    lost_after_s: float = 5.0  # wall seconds without HEARTBEAT before a vehicle is lost
    signing_key: bytes | None = None
    assign: dict = field(default_factory=dict)  # sysid -> plan vehicle id (default: in order)
    connect_timeout_s: float = 30.0
    ready_timeout_s: float = 60.0
    protocol_timeout_s: float = 1.5  # mission protocol: wait per message before a retry
    protocol_retries: int = 5  # mission protocol and commands: resends before giving up
    max_items: int | None = None  # items per upload at most (segments below the capacity)
    timeout_s: float | None = None  # after this many wall seconds: ask, or bring them home
    tlog: bool = True
    forward: object = None  # gcs.forward.Forwarder: the fleet's MAVLink relayed (--forward)
    live: bool = True  # rich status table on a terminal, event lines otherwise
    plot: bool = True
    auto_turnaround: bool = False  # between sorties: a fresh battery reported is enough
                                   # (simulators, SITL); else the operator confirms too
    from_where_they_stand: bool = False  # a vehicle off its launch point: plan again with
                                         # its base where it stands (else it is refused)
    swap_silence_s: float = SWAP_SILENCE_S  # wall s one down for its battery swap may be
                                            # silent (powered down) before it is lost

    @property
    def protocol(self) -> dict:
        """Keyword arguments of the mission protocol calls (timeouts and retries)."""
        return {"timeout_s": self.protocol_timeout_s, "retries": self.protocol_retries}


@dataclass
class Departure:
    """A vehicle to send on its way at fleet time ``due``: "launch" (its takeoff) or
    "resume" (flying on after a re-plan held it)."""

    due: float
    kind: str
    route: object


def _at_waypoint(w, lat, lon, alt_amsl) -> bool:
    """A vehicle at (lat, lon, alt_amsl) stands at waypoint ``w``."""
    return abs(w.alt_amsl - alt_amsl) < AT_WAYPOINT_M and \
        distance_m(lat, lon, w.lat, w.lon) < AT_WAYPOINT_M


def _fresh(battery_pct) -> bool:
    """A fresh battery reported, or none reported at all (nothing to wait for)."""
    return battery_pct is None or battery_pct >= FRESH_BATTERY_PCT


def _finite_or_none(x):
    return None if x is None or not math.isfinite(x) else round(float(x), 2)


def _start(route):
    """Where a route's vehicle must stand to start it: its launch point, or under its
    first waypoint when the plan has none (None for a route without waypoints)."""
    if route.launch is not None:
        return route.launch
    return route.waypoints[0] if route.waypoints else None


def _start_name(route) -> str:
    return "the launch point" if route.launch is not None else "under the first waypoint"


class FlightError(Exception):
    """The flight could not go on (a vehicle refused its start, re-tasking failed)."""


class _TimedOut(Exception):
    """--timeout reached while vehicles were still flying."""


def assign_vehicles(plan: Plan, sysids: list, assign: dict) -> dict:
    """{sysid: VehicleRoute}: by ``assign`` (sysid -> vehicle id), else in order."""
    routes = {v.id: v for v in plan.vehicles}
    if assign:
        unknown = [i for i in assign.values() if i not in routes]
        if unknown:
            raise InputError("--assign", f"the plan has no vehicle {unknown[0]} "
                                         f"(vehicles {sorted(routes)})")
        missing = [s for s in assign if s not in sysids]
        if missing:
            raise InputError("--assign", f"no vehicle with system id {missing[0]} answered "
                                         f"(found {sysids})")
        return {s: routes[i] for s, i in assign.items()}
    if len(sysids) < len(plan.vehicles):
        raise InputError("--connect", f"the plan has {len(plan.vehicles)} vehicles but only "
                                      f"{len(sysids)} answered ({sysids})")
    return {s: v for s, v in zip(sorted(sysids), plan.vehicles)}


class Flight:
    """One flight of a plan; `run` does everything, the parts are there for tests."""

    def __init__(self, plan_dir, urls, options: FlyOptions, log=None, ctx=None):
        """``ctx``: the plan's `PlanningContext` when it is in memory (`gcs demo`);
        otherwise it is loaded from the plan folder."""
        self.plan_dir = Path(plan_dir)
        self.plan = Plan.load(self.plan_dir)
        self.urls = list(urls)
        self.options = options
        self.output = Path(options.output)
        self.log = log or (lambda text: None)
        self.monitor = Monitor(options.lost_after_s, on_event=self._on_event,
                               track_tolerance_m=self.plan.params.get("track_tolerance_m"))
        self.clock = FleetClock(self.monitor)
        # a vehicle down between two sorties is still part of the flight: one that goes
        # silent there is lost (and re-planned for), not waited for
        self.monitor.awaited = lambda: {s for s, parts in list(self.later.items())
                                        if parts and self.monitor.vehicles[s].state != LOST}
        self.monitor.swapping = self._swapping
        self.monitor.swap_silence_s = options.swap_silence_s
        self.departures = {}      # sysid -> Departure: takeoffs and resumes yet to come
        self._departing = {}      # sysid -> (thread, error, cancel) of departures under way
        self._resuming = set()    # of them, vehicles a re-plan held, flying on
        self._waiting_for = {}    # sysid -> the vehicle its base column waits for
        self._lifting = {}        # sysid -> launch point of the base column claimed for it
        self._column_lock = threading.Lock()
        self._lifted = []         # (sysid, launch begun, lifted off): monitor times
        self.latency_s = 0.0      # fleet s from a launch's first command to its liftoff
        self.guard = None
        self.min_separation_m = None  # the plan's, proven again in `prepare`
        self.segments = Segments(self.monitor, options.protocol, options.max_items)
        self.start_unix = time.time()
        self.link = None
        self.retasks = []
        self.later = {}           # sysid -> [(offset, sortie route)] after this one
        self.offset = {}          # sysid -> fleet s of t = 0 of its route's times (a re-plan's)
        self._waiting_battery = {}  # sysid -> the sortie waiting for a fresh battery
        self.swapped = set()      # sysids whose battery swap the operator confirmed
        self._route_seen = {}     # sysid -> (route, own clock s, route time s) first seen
        self._pace = {}           # sysid -> times slower than planned on its route so far
        self.paces = {}           # sysid -> {sortie: its pace when last timed} (the report's)
        self._late = {}           # the same, for those the battery watch brought home
        self._late_acted = set()  # ... in their sortie now: once a sortie (`_watch_batteries`)
        self._sortie_began = {}   # sysid -> SortieDraw since its last liftoff
        self.spent = set()        # sysids the battery watch sent home: they stay down
        # fly at the speed the plan's times assume, as `gcs plan` writes the files
        self.mission_options = MissionOptions(speed_mps=self.plan.params.get("speed_mps"))
        self.ctx = ctx
        self._ctx_ready = threading.Event()
        self._ctx_error = None
        self.missions = None      # (route id, firmware) -> CheckedMission, once prepared
        self.surface = None
        self.timed_out = False
        self.stopped = None       # why monitoring ended early ("interrupted", "timed out")
        self.error = None         # what stopped the flight (FlightError)

    # -- stages -------------------------------------------------------------------------
    def prepare(self) -> None:
        """Read the plan and prove every route's mission, for each autopilot, before
        any connection: InputError naming the plan and vehicle if one fails."""
        if self.missions is not None:
            return
        if self.ctx is None:
            from planner.pipeline import load_context

            self.ctx = load_context(self.plan_dir, self.plan)
        self.surface = self.ctx.surface
        clearance = self.plan.params.get("clearance_m")
        missions = {}
        for route in self.plan.vehicles:
            if not route.waypoints:
                continue
            for firmware in NAMES:      # every sortie's, the first kept for the upload
                for j, part in reversed(list(enumerate(route.sortie_routes(), start=1))):
                    mission = vehicle_mission(part, firmware, self.mission_options)
                    missions[route.id, firmware] = checked(
                        mission, self.surface, clearance,
                        name=f"{self.plan_dir / PLAN_FILE}: vehicle {route.id}"
                             + (f" sortie {j}" if route.sorties else ""))
        self.missions = missions
        terrain = self.surface.terrain
        # the fleet keeps apart as planned: proven again from what the missions fly
        self.min_separation_m = prove_separated(self.plan, terrain,
                                                self.ctx.scenario.travel_params(),
                                                source=str(self.plan_dir / PLAN_FILE))

        def ground(lat, lon):
            x, y = terrain.from_lonlat(lon, lat)
            return float(terrain.ground(x, y)[0])

        self.monitor.ground = ground

    def run(self, status=None, on_interrupt=None, on_timeout=None) -> dict:
        """Fly the plan to the end; returns the report (also written to flight.json).

        Ctrl-C while monitoring calls ``on_interrupt()``, and the end of
        ``timeout_s`` with vehicles still flying calls ``on_timeout()`` (default:
        "home"): "home" re-tasks every vehicle in the air home along hidden paths
        (never plain RTL) and keeps monitoring; anything else leaves them on their
        missions and stops. A FlightError is re-raised after the report is written."""
        self.prepare()
        self.output.mkdir(parents=True, exist_ok=True)
        threading.Thread(target=self._prepare_context, daemon=True,
                         name="replan-context").start()
        self.monitor.watch_losses()
        try:
            self.connect()
            self.locate()
            self.check_failsafes()
            self.check_rates()
            self.upload()
            self.start()
            self._watch_and_answer(status, on_interrupt, on_timeout or (lambda: "home"))
        except FlightError as exc:
            self.error = str(exc)
            self.monitor.event(None, f"failed: {exc}")
            self._home_after_failure()
        finally:
            self.monitor.close()
            if self.link is not None:
                self.link.close()
        report = self.report()
        self.write(report)
        if self.error is not None:
            raise FlightError(self.error)
        return report

    def _watch_and_answer(self, status, on_interrupt, on_timeout) -> None:
        """Monitor; on Ctrl-C or the timeout ask what to do (once each time)."""
        try:
            self.watch(status, self.options.timeout_s)
            return
        except KeyboardInterrupt:
            why = "interrupted"
            choice = on_interrupt() if on_interrupt is not None else "leave"
        except _TimedOut:
            why = f"timed out after {self.options.timeout_s:g} s"
            self.timed_out = True
            choice = on_timeout()
        self.monitor.event(None, f"{why}: {choice}")
        self.stopped = why
        if choice != "home":
            return
        if self._bring_home(status, bounded=self.options.timeout_s is not None):
            self.stopped = None

    def _bring_home(self, status, bounded: bool) -> bool:
        """Every vehicle in the air home along hidden paths (never RTL), watched until
        down; ``bounded``: for no longer than the flights home take, twice over (at
        least `HOME_WAIT_S`). False when stopped before they all landed."""
        self.retask(home=True)
        bound = max(self.options.timeout_s or 0.0, HOME_WAIT_S, self._home_wall_s()) \
            if bounded else None
        try:
            self.watch(status, bound)
            return True
        except (KeyboardInterrupt, _TimedOut):
            self.monitor.event(None, "stopped while bringing the vehicles home")
            return False

    def _home_after_failure(self) -> None:
        """The flight failed (a start refused, an upload that cannot be done) with
        vehicles in the air: they are not left on their missions with nobody
        watching (no guard, no re-plan on a loss), but brought home by hidden paths
        (never RTL) and watched until down, as on a timeout."""
        m = self.monitor
        up = [s for s, v in sorted(m.vehicles.items()) if v.airborne and not v.finished]
        if not up:
            return
        m.event(None, "the flight failed: the vehicles in the air are brought home by "
                      "hidden paths", vehicles=up)
        self.departures.clear()
        for parts in self.later.values():
            parts.clear()
        try:
            self._bring_home(None, bounded=True)     # nobody is asked: never forever
        except FlightError as exc:
            m.event(None, f"could not bring them all home: {exc}")

    def _home_wall_s(self) -> float:
        """Wall seconds the flights home take, twice over: the re-plan's mission time
        at the fleet clock's rate (a simulator on a busy machine runs slower)."""
        planned = self.retasks[-1].planned if self.retasks else {}
        return 2.0 * float(planned.get("mission_time_s") or 0.0) / max(self.clock.rate(), 1e-3)

    def _prepare_context(self) -> None:
        """The travel times between viewpoints (of an area planned in parts: the
        overlay each part's times come from), which only re-planning needs:
        computed while the vehicles start, so that a loss finds them ready."""
        try:
            if self.ctx.in_parts:
                self.ctx.viewpoint_overlay()
            else:
                self.ctx.travel  # noqa: B018 - computed once, kept by the context
        except Exception as exc:  # reported when the context is needed
            self._ctx_error = exc
        self._ctx_ready.set()

    def context(self):
        self._ctx_ready.wait()
        if self._ctx_error is not None:
            raise self._ctx_error
        return self.ctx

    def connect(self) -> None:
        o = self.options
        expect = sorted(o.assign) if o.assign else len(self.plan.vehicles)
        tlog = str(self.output / TLOG_PATTERN) if o.tlog else None
        try:
            self.link = GroundLink.open(self.urls, o.signing_key, expect=expect,
                                        timeout_s=o.connect_timeout_s, tlog=tlog,
                                        forward=o.forward)
        except LinkError as exc:
            raise FlightError(str(exc)) from None
        vehicles = self.link.vehicles
        for sysid, route in assign_vehicles(self.plan, list(vehicles), o.assign).items():
            link = vehicles[sysid]
            mission = self.missions.get((route.id, link.flavour))
            if mission is None:
                raise FlightError(f"vehicle {sysid}: its autopilot ({link.flavour}) is neither "
                                  f"{' nor '.join(NAMES)}: no mission for it")
            self._follow(link, route, mission)
            self.monitor.event(sysid, "connected", flavour=link.flavour, vehicle=route.id,
                               items=len(mission.items))

    def route_missions(self, route, firmware) -> RouteMissions:
        """The missions that fly ``route`` with ``firmware``, each proven by the gate
        (`checked`). The plan's waypoints are already the fewest the leg proofs allow
        (its schedule counts a stop at each): only repeated places are left out."""
        clearance = self.plan.params.get("clearance_m")
        name = f"{self.plan_dir / PLAN_FILE}: vehicle {route.id}"
        return RouteMissions(route, firmware, self.mission_options,
                             lambda mission: checked(mission, self.surface, clearance, name=name),
                             fly=fewer_waypoints(route))

    def upload(self) -> None:
        m = self.monitor
        missions = {}
        for sysid, v in m.vehicles.items():
            try:
                missions[sysid] = self.route_missions(v.route, m.links[sysid].flavour)
            except InputError as exc:
                raise FlightError(str(exc)) from None

        def one(sysid):
            def learned(capacity, how):
                m.event(sysid, "mission capacity", capacity=capacity, how=how)

            mission = upload_route(m.links[sysid], missions[sysid], self.options.protocol,
                                   on_capacity=learned, limit=self.options.max_items)
            m.set_mission(sysid, mission)
            self.segments.fly(sysid, missions[sysid])
            whole = len(missions[sysid])
            m.event(sysid, "mission uploaded and verified", items=len(mission),
                    **({} if mission.final else {"route_items": whole, "segment": 1}))

        self._all(one, "upload", (MissionError, InputError))

    def start(self) -> None:
        """The fleet clock starts; every vehicle takes off at its planned time
        (`Departure`): those due now here, the others from `watch`."""
        m = self.monitor
        self.guard = SeparationGuard(
            m, float(self.plan.params.get("separation_m", 0.0)),
            {s: v.route.priority for s, v in m.vehicles.items()}, self.clock,
            airborne=lambda: [s for s, v in m.vehicles.items()
                              if v.state in (FLYING, HOLDING) and v.airborne],
            hold=lambda s: self._set_mode(s, "hold_mode", HOLDING),
            resume=self._fly_on,
            travel=self.ctx.scenario.travel_params(), stop_s=stop_time(self.plan.params),
            on_pad=m.on_pad, short=self._short_of_battery, waiting=self._waiting_s,
            lands_here=self._lands_here, land=self._land_here)
        # every vehicle ready to arm first: then each start takes about as long, and the
        # takeoffs keep the plan's spacing
        self._all(lambda s: commands.wait_ready(m.links[s], self.options.ready_timeout_s),
                  "start", commands.CommandError)
        for sysid, v in m.vehicles.items():
            if v.state != LOST:
                self.departures[sysid] = Departure(v.route.takeoff_s, "launch", v.route)
        self._depart_due()

    def _launch(self, sysid, route, cancel) -> None:
        m = self.monitor
        begun, lifted = m.now(), []

        def liftoff():
            if not lifted:          # sent up: from now a re-plan holds it in the air
                m.event(sysid, "taking off")
            lifted.append(True)
            self._lifted.append((sysid, begun, m.now()))
            track = m.vehicles[sysid].track
            self._sortie_began[sysid] = SortieDraw(
                m.now(), self._own_clock(sysid), m.links[sysid].state.battery_pct, len(track),
                track[-1][3] if track else None, route.waypoints[0].sortie,
                route.mission_time_s - route.takeoff_s)
            self._late_acted.discard(sysid)
        m.set_state(sysid, STARTING)
        try:
            # the column is looked at again as it arms: one held on the ground (refused
            # arming, a late start) may find another vehicle launched into it meanwhile
            column = SimpleNamespace(claim=lambda: self._claim_column(sysid, route),
                                     release=lambda: self._lifting.pop(sysid, None))
            commands.start_mission(m.links[sysid], route.waypoints[0].alt_amsl,
                                   ready_timeout_s=self.options.ready_timeout_s,
                                   retries=self.options.protocol_retries,
                                   on_liftoff=liftoff, cancel=cancel, column=column)
        except commands.StartCancelled:
            self._lifting.pop(sysid, None)
            # sent up: the re-plan holds it where it is; never sent up: it stays down
            if not lifted:
                m.call_off(sysid)
            return
        except BaseException:
            self._lifting.pop(sysid, None)
            if not lifted:
                m.call_off(sysid)     # still down: not one a re-plan would hold in the air
            raise
        m.set_state(sysid, FLYING)  # its column is kept until it is seen airborne

    def _short_of_battery(self, sysid) -> bool:
        """Sent home by the battery watch on this sortie, or down to the plan's reserve:
        the separation guard holds the other of a pair first."""
        if not self.plan.params.get("endurance_min"):
            return False
        pct = self.monitor.links[sysid].state.battery_pct
        return sysid in self.spent or sysid in self._late_acted or \
            (pct is not None and pct <= float(self.plan.params.get("reserve_pct") or 0.0))

    def _call_off_starts(self) -> None:
        """Stop every start sequence under way (a re-plan takes the vehicles over) and
        wait for their threads, so nothing they send comes after the re-plan's hold."""
        for thread, _, cancel in self._departing.values():
            cancel.set()
        for sysid, (thread, _, _) in list(self._departing.items()):
            thread.join(CALL_OFF_WAIT_S)
            if not thread.is_alive():
                del self._departing[sysid]

    def _resume(self, sysid, route=None, cancel=None) -> None:
        Retasker.resume(self.monitor, sysid, self.options.protocol_retries)
        self.monitor.set_state(sysid, FLYING)

    def _set_mode(self, sysid, which, state) -> None:
        link = self.monitor.links[sysid]
        commands.set_mode(link, getattr(commands.autopilot(link), which),
                          retries=self.options.protocol_retries)
        self.monitor.set_state(sysid, state)

    def _fly_on(self, sysid) -> None:
        """A vehicle the guard held flies on toward the item it was flying to. Where
        the firmware would climb straight up where it holds, that item being higher
        (`resume_climbs_above_m`, PX4), the rest of its route goes up from where it
        holds (`Segments.fly_on_here`). Where it would go back to the item before
        (`resume_rewinds`, PX4), along no proven leg, its current item is moved away
        and back first: then the mission starts again from where it is."""
        link = self.monitor.links[sysid]
        profile, seq = commands.autopilot(link), link.state.mission_seq
        if self._climbs_first(sysid, profile, seq) and self.segments.can_fly_on_here(sysid):
            try:
                return self.segments.fly_on_here(sysid)
            except (MissionError, InputError) as exc:     # its mission stands as it was
                self.monitor.event(sysid, "upload from where it holds failed: flies on as "
                                          "it is", error=str(exc))
        if profile.resume_rewinds and seq is not None and seq > profile.first_item:
            self._set_current(sysid, seq)
        self._set_mode(sysid, "mission_mode", FLYING)

    def _set_current(self, sysid, seq) -> None:
        """Its mission's current item ``seq``; where the firmware would go back to the
        item before (`resume_rewinds`), moved there and on: then the mission starts
        again from where it is."""
        link = self.monitor.links[sysid]
        rewinds = commands.autopilot(link).resume_rewinds
        for item in (seq - 1, seq) if rewinds else (seq,):
            commands.set_current(link, item, retries=self.options.protocol_retries)

    def _lands_here(self, sysid) -> bool:
        """In its base column (within `LAUNCH_COLUMN_M` of it) with nothing left to
        photograph and only the column's top before the landing its mission ends
        with: landing from where it is flies the rest of its route's proven column
        (hidden because its top is), without the climb to the top."""
        v, state = self.monitor.vehicles[sysid], self.monitor.links[sysid].state
        base = v.route.landing
        if base is None or state.lat is None or not self._homebound(sysid) or \
                self._land_item(sysid) is None:
            return False
        rest = v.route.waypoints[self._next_waypoint(sysid):]
        return all(distance_m(p.lat, p.lon, base.lat, base.lon) <= LAUNCH_COLUMN_M
                   for p in [state, *rest])

    def _land_item(self, sysid):
        """The sequence number of the landing its mission ends with, None without one."""
        mission = self.monitor.vehicles[sysid].mission
        items = mission.items if mission is not None else []
        return items[-1].seq if items and int(items[-1].command) == NAV_LAND else None

    def _land_here(self, sysid) -> None:
        """Its mission flown on from its landing (`_lands_here`; a mission changed
        since without one: flown on as it is)."""
        land = self._land_item(sysid)
        if land is None:
            return self._fly_on(sysid)
        self._set_current(sysid, land)
        self._set_mode(sysid, "mission_mode", FLYING)

    def _climbs_first(self, sysid, profile, seq) -> bool:
        """Whether ``sysid``, its mission flown on now, would first climb straight up
        where it is: its next position item is higher than it by more than the
        firmware allows (`resume_climbs_above_m`)."""
        climb, alt = profile.resume_climbs_above_m, self.monitor.links[sysid].state.alt_amsl
        mission = self.monitor.vehicles[sysid].mission
        if climb is None or seq is None or alt is None or mission is None:
            return False
        ahead = next((it for it in mission.items[seq:] if it.is_position), None)
        return ahead is not None and ahead.z > alt + climb

    def depart(self, sysid, after_s, kind, route) -> None:
        """``sysid`` takes off (``kind`` "launch") or flies on ("resume") ``after_s``
        fleet seconds from now (a re-plan's schedule)."""
        self.departures[sysid] = Departure((self.clock.now() or 0.0) + after_s, kind, route)

    def _depart_due(self) -> None:
        """Send the vehicles whose time has come, each in its own thread; a takeoff
        waits while another airborne vehicle is in its base column. A failure of a
        vehicle still heard from stops the flight."""
        m = self.monitor
        self._anchor_clock()
        now = self.clock.now()
        if now is None:     # the clock starts at the first takeoff: those go now, alone
            now = -math.inf if self._departing else \
                min((d.due for d in self.departures.values()), default=0.0)
        for sysid, (thread, error, _) in list(self._departing.items()):
            if thread.is_alive():
                continue
            del self._departing[sysid]
            if error and m.vehicles[sysid].state != LOST:
                raise FlightError(f"start failed: {error[0]}")
        for sysid, d in list(self.departures.items()):
            if m.vehicles[sysid].state == LOST:
                del self.departures[sysid]
                continue
            early = self.latency_s if d.kind == "launch" else 0.0
            if d.due - early > now or sysid in self._departing:
                continue
            if d.kind == "launch" and not self._column_clear(sysid, d.route):
                continue
            del self.departures[sysid]
            error, cancel = [], threading.Event()
            run = self._launch if d.kind == "launch" else self._resume
            if d.kind == "resume":
                self._resuming.add(sysid)

            def go(s=sysid, route=d.route, run=run, error=error, cancel=cancel):
                try:
                    run(s, route, cancel)
                except commands.CommandError as exc:
                    error.append(exc)
                finally:
                    self._resuming.discard(s)
            thread = threading.Thread(target=go, daemon=True, name=f"depart-{sysid}")
            self._departing[sysid] = (thread, error, cancel)
            thread.start()

    def _waiting_s(self, sysid):
        """Fleet seconds until a vehicle a re-plan holds flies on (0 while it is
        being sent on), None when it waits for no re-plan: the separation guard
        leaves such a vehicle to the re-plan's schedule."""
        if sysid in self._resuming:
            return 0.0
        d = self.departures.get(sysid)
        if d is None or d.kind != "resume":
            return None
        return max(0.0, d.due - (self.clock.now() or 0.0))

    def _anchor_clock(self) -> None:
        """The fleet clock reads a vehicle's planned takeoff time when it is seen
        leaving the ground (t = 0: the first takeoff), and each launch is begun as
        much earlier as the last one took from its first command to that moment
        (arming, the takeoff command: `latency_s`), so takeoffs keep the plan's
        spacing whatever the ground station's and the vehicles' own delays."""
        m = self.monitor
        while self._lifted:
            sysid, begun, lifted = self._lifted.pop(0)
            if not self.clock.started:
                self.clock.start(m.vehicles[sysid].route.takeoff_s + (m.now() - lifted))
            self.latency_s = (lifted - begun) * self.clock.rate()

    def _claim_column(self, sysid, route) -> bool:
        """`_column_clear`, and if so the column kept for ``sysid`` from its arming
        until it is seen airborne (then its position keeps it) or its arming is refused:
        two vehicles whose start sequences overlap (one whose arming was refused for a
        while) would otherwise both find the column clear while on the ground, arm
        together and climb it one above the other."""
        with self._column_lock:
            if not self._column_clear(sysid, route):
                return False
            self._lifting[sysid] = route.launch
            return True

    def _column_clear(self, sysid, route) -> bool:
        """No other airborne vehicle within the separation of the column above its
        base (from the ground to the separation above its takeoff top), and the
        column claimed by no other vehicle lifting off (`_claim_column`)."""
        m = self.monitor
        sep = float(self.plan.params.get("separation_m", 0.0))
        launch = route.launch
        if sep <= 0 or launch is None:
            return True
        for other, base in list(self._lifting.items()):
            v = m.vehicles[other]
            if v.airborne or v.state in (LOST, LANDED):
                self._lifting.pop(other, None)      # where it is now speaks for it
            elif other != sysid and base is not None and \
                    distance_m(launch.lat, launch.lon, base.lat, base.lon) < sep:
                return self._wait_for(sysid, other)
        top = route.waypoints[0].alt_amsl + sep
        for other, v in m.vehicles.items():
            s = m.links[other].state
            if other == sysid or not v.airborne or v.state in (LOST, LANDED) or s.lat is None:
                continue
            h = distance_m(launch.lat, launch.lon, s.lat, s.lon)
            below = max(launch.alt_amsl - s.alt_amsl, 0.0, s.alt_amsl - top)
            if math.hypot(h, below) < sep:
                return self._wait_for(sysid, other)
        self._waiting_for.pop(sysid, None)
        return True

    def _wait_for(self, sysid, other) -> bool:
        """False, said once per vehicle waited for."""
        if self._waiting_for.get(sysid) != other:
            self._waiting_for[sysid] = other
            self.monitor.event(sysid, f"takeoff waits: vehicle {other} is in its base column")
        return False

    def locate(self) -> None:
        """Wait for every vehicle's position (ArduPilot reports none before its EKF
        has an origin), then `check_positions`: before anything is uploaded or armed."""
        m = self.monitor
        self._all(lambda sysid: commands.wait_position(m.links[sysid],
                                                       self.options.ready_timeout_s),
                  "locating", commands.CommandError)
        self.check_positions()

    def check_positions(self) -> None:
        """Before anything is armed: every vehicle stands at its route's launch point
        (its reported position), within the plan's track tolerance, the room its
        takeoff column is proven with (at least `MIN_LAUNCH_TOLERANCE_M`: GNSS on
        the ground). A vehicle elsewhere would climb and fly a first leg nobody
        proved hidden: FlightError naming each one and how far off it stands, or
        with ``from_where_they_stand`` the fleet planned again from where they
        stand (`plan_from_where_they_stand`).
        (Its home is not compared: ArduPilot and PX4 both set home where they arm.)"""
        off = self._off_launch()
        if off and self.options.from_where_they_stand:
            self.plan_from_where_they_stand(off)
            off = self._off_launch()          # the new plan's bases: where they stand
        if off:
            lines = [f"vehicle {sysid} stands {d:.1f} m from {_start_name(route)} of route "
                     f"{route.id} ({lat:.7f},{lon:.7f}, not {_start(route).lat:.7f},"
                     f"{_start(route).lon:.7f})" for sysid, route, d, lat, lon in off]
            for line in lines:
                self.monitor.event(None, f"refused: {line}")
            raise FlightError("; ".join(lines) + f": each must stand within "
                              f"{self._launch_tolerance():g} m of where its route starts (the "
                              "plan's track tolerance) before it is armed")

    def _off_launch(self) -> list:
        """[(sysid, route, metres, lat, lon)] of the vehicles standing farther from their
        route's launch point (or, for a plan without one, from under its first
        waypoint: it climbs straight up to it) than the launch tolerance."""
        tolerance = self._launch_tolerance()
        off = []
        for sysid, v in sorted(self.monitor.vehicles.items()):
            launch, s = _start(v.route), self.monitor.links[sysid].state
            if launch is None or v.state == LOST or s.lat is None:
                continue
            d = distance_m(launch.lat, launch.lon, s.lat, s.lon)
            if d > tolerance:
                off.append((sysid, v.route, d, s.lat, s.lon))
        return off

    def plan_from_where_they_stand(self, off) -> None:
        """The operator's choice for vehicles off their launch points: the plan's
        scenario planned again with each such vehicle's base where it stands (the
        others' where planned), written to ``PLAN_FROM_HERE`` in the output folder and
        flown instead, every mission and the separation proven again as any plan's.
        A vehicle standing where no hidden takeoff is possible is refused by name."""
        from gcs.plan_folder import write_plan_folder
        from planner.pipeline import allocate, launch_starts

        m = self.monitor
        here = {sysid for sysid, *_ in off}
        for sysid, route, d, lat, lon in off:
            m.event(sysid, f"stands {d:.1f} m from {_start_name(route)} of route "
                           f"{route.id}: planning again from where it stands")

        def base(sysid, route):      # where it stands, unless it stands where planned
            at = _start(route) if sysid not in here else None
            state = m.links[sysid].state
            return (at.lat, at.lon) if at is not None else (state.lat, state.lon)

        by_route = {v.route.id: base(sysid, v.route) for sysid, v in m.vehicles.items()}
        launch = [by_route.get(v.id) or (_start(v).lat, _start(v).lon)
                  for v in self.plan.vehicles]
        ctx = self.context()
        for sysid, _, _, lat, lon in off:      # named, before the fleet is planned
            try:
                launch_starts(replace(ctx, scenario=replace(ctx.scenario, launch=[(lat, lon)],
                                                            uavs=1)))
            except InputError as exc:
                raise FlightError(f"cannot plan from where the vehicles stand: vehicle "
                                  f"{sysid}: {exc.problem}") from None
        ctx = replace(ctx, scenario=replace(ctx.scenario, launch=launch))
        try:
            starts = launch_starts(ctx)
            outcome = allocate(ctx, len(self.plan.vehicles), starts, log=self.log)
            folder = self.output / PLAN_FROM_HERE
            write_plan_folder(folder, ctx, outcome)
        except InputError as exc:
            raise FlightError(f"cannot plan from where the vehicles stand: {exc}") from None
        self._fly_instead(folder, ctx)
        m.event(None, f"flying the plan made from where they stand ({folder}): coverage "
                      f"time {outcome.plan.metrics['coverage_time_s'] / 60:.1f} min")

    def _fly_instead(self, folder, ctx) -> None:
        """Fly the plan in ``folder`` (made in memory as ``ctx``) with the vehicles
        connected now, each on the route of the same number, proven as `prepare` does."""
        self.plan_dir, self.plan = Path(folder), Plan.load(folder)
        self.ctx, self.missions = ctx, None
        self.prepare()
        routes = {v.id: v for v in self.plan.vehicles}
        for sysid, v in list(self.monitor.vehicles.items()):
            link = self.monitor.links[sysid]
            self._follow(link, routes[v.route.id], self.missions[v.route.id, link.flavour])

    def _follow(self, link, route, mission) -> None:
        """The monitor follows ``link`` flying ``route``'s first sortie as ``mission``;
        its later sorties wait their turn (`_next_sorties`)."""
        first, *later = route.sortie_routes()
        self.monitor.follow(link, route.id, first, mission)
        self.later[link.sysid] = [(0.0, part) for part in later]

    def check_failsafes(self) -> None:
        """Say, one line per vehicle, what its autopilot does on a low battery
        (ArduPilot BATT_FS_LOW_ACT and BATT_FS_CRT_ACT, PX4 COM_LOW_BAT_ACT): anything
        but a warning or a landing where it is flies a path nobody proved hidden, in
        view of the outposts. The plan's reserve keeps the battery above it; the
        battery watch acts first."""
        m = self.monitor
        for sysid, v in sorted(m.vehicles.items()):
            link = m.links[sysid]
            failsafes = commands.autopilot(link).battery_failsafes
            if not failsafes or v.state == LOST:
                continue
            said, unproven = [], False
            for name, actions in failsafes:
                value = commands.read_param(link, name, retries=1)
                if value is None:
                    said.append(f"{name} not answered (what it does is unknown)")
                    continue
                does = actions.get(int(value), f"value {int(value)} (see the autopilot's manual)")
                said.append(f"{name} = {int(value)}, {does}")
                unproven |= not does.startswith(HIDDEN_FAILSAFES)
            m.event(sysid, "battery failsafe: " + "; ".join(said)
                    + (": if one fired, that flight is not proven hidden from the outposts"
                       if unproven else ""))

    def check_rates(self) -> None:
        """Say, one line per vehicle, where its autopilot's own limits on a mission's
        speed, climb or descent (the profile's `rate_limits`: ArduPilot
        WPNAV_SPEED_UP / _DN, PX4 MPC_XY_VEL_MAX, MPC_Z_V_AUTO_UP / _DN) are below the
        plan's: the legs they cap take longer than planned, and the fleet's
        schedule, its separation and each sortie's battery were planned on the
        plan's figures."""
        m = self.monitor
        for sysid, v in sorted(m.vehicles.items()):
            link = m.links[sysid]
            if v.state == LOST:
                continue
            slower = []
            for name, rate, unit in commands.autopilot(link).rate_limits:
                planned, value = self.plan.params.get(rate), commands.read_param(link, name,
                                                                                  retries=1)
                if planned is not None and value is not None and \
                        value * unit < float(planned) - RATE_SLACK_MPS:
                    slower.append(f"{name} = {value:g} ({value * unit:g} m/s, the plan's "
                                  f"{rate} {float(planned):g})")
            stops = self._stop_said(commands.autopilot(link).name)
            if stops:
                slower.append(stops)
            if slower:
                m.event(sysid, "slower than planned: " + "; ".join(slower) + ": its legs take "
                        "longer than the plan's times, on which its schedule, separation and "
                        "battery were planned; set the parameters to the plan's rates, or "
                        "plan with the vehicle's")

    def _stop_said(self, firmware):
        """What a vehicle of ``firmware`` loses at a waypoint beyond what the plan
        counts, said; None when no more (a PX4 vehicle flying a plan made for
        ArduPilot stops at each: 2.7 s more a waypoint at 12 m/s)."""
        planned = stop_time(self.plan.params)
        own = stop_time(dict(self.plan.params, firmware=firmware))
        if own <= planned + 1e-6:
            return None
        return (f"each waypoint {own:.1f} s ({firmware} stops at each) where the plan counts "
                f"{planned:.1f} s (planned for {self.plan.params.get('firmware') or 'ardupilot'})")

    def _launch_tolerance(self) -> float:
        return max(float(self.plan.params.get("track_tolerance_m", LAUNCH_TOLERANCE_M)),
                   MIN_LAUNCH_TOLERANCE_M)

    def _all(self, fn, what, expected) -> None:
        """fn on every vehicle at once. A vehicle that fails and then falls silent
        was lost during this stage (the flight goes on); any other failure stops it."""
        sysids = [s for s, v in sorted(self.monitor.vehicles.items()) if v.state != LOST]
        self._lost_or_failed(fn, sysids, what, expected)

    def _lost_or_failed(self, fn, sysids, what, expected) -> list:
        """fn on ``sysids`` at once; those that fell silent meanwhile (now or within
        ``lost_after_s`` of failing) are lost, returned, and re-tasked for by `watch`;
        any other failure stops the flight (FlightError for an ``expected`` one)."""
        m = self.monitor
        errors = _in_parallel(fn, sysids, m)  # a vehicle falling silent is not waited for
        failed = {s: e for s, e in errors.items() if e is not None}
        end = time.monotonic() + self.options.lost_after_s + 1.0
        while failed and time.monotonic() < end and any(m.vehicles[s].state != LOST
                                                        for s in failed):
            m.check_losses()
            time.sleep(LOOP_S)
        for sysid, exc in sorted(failed.items()):
            if m.vehicles[sysid].state != LOST:
                if isinstance(exc, expected):
                    raise FlightError(f"{what} failed: {exc}") from None
                raise exc
        lost = [s for s in sysids if m.vehicles[s].state == LOST]
        for sysid in lost:
            error = errors.get(sysid)  # none when it fell silent before failing
            m.event(sysid, f"lost during {what}", **({"error": str(error)} if error else {}))
        return lost

    def watch(self, status=None, timeout_s=None) -> None:
        """Monitor until every vehicle has landed or is lost; re-task on each loss.
        _TimedOut after ``timeout_s`` wall seconds with vehicles still flying."""
        m = self.monitor
        end = None if timeout_s is None else time.monotonic() + timeout_s
        while True:
            # every loss found so far, here or while waiting on vehicles (uploads,
            # segment switches): the last one flying may leave the others down
            m.check_losses()
            if m.take_losses():
                self.retask()
            self._next_sorties()
            self._watch_batteries()
            # a loss found since (on the ground as its next sortie uploads, or by the
            # loss thread) is re-tasked for first: the survivors, down already, fly its
            # work (the flight once ended with it unflown)
            if m.all_finished() and not self.departures and not m.awaited() and \
                    not m.losses_waiting():
                break
            self._depart_due()
            if self.guard is not None:
                self.guard.step()
            due = self.segments.due()
            if due:
                self.next_segments(due)
            if status is not None:
                status(m.status_rows())
            if end is not None and time.monotonic() > end and not m.all_finished():
                raise _TimedOut()
            time.sleep(LOOP_S)
        if status is not None:
            status(m.status_rows())

    def _next_sorties(self) -> None:
        """A vehicle down at its base after a sortie flies its next one at its planned
        time, once its battery is swapped (`_battery_ready`); one that landed
        elsewhere flies no more sorties."""
        m = self.monitor
        for sysid, parts in self.later.items():
            v = m.vehicles[sysid]
            if not parts or v.state != LANDED or sysid in self.departures:
                continue
            offset, route = parts[0]
            state = m.links[sysid].state
            if state.lat is None or distance_m(route.launch.lat, route.launch.lon, state.lat,
                                               state.lon) > self._launch_tolerance():
                parts.clear()
                m.event(sysid, "landed away from its base: its later sorties are not flown")
                continue
            if not self._battery_ready(sysid, route, state.battery_pct):
                continue
            uploaded = {}

            def upload(s, route=route):
                missions = self.route_missions(route, m.links[s].flavour)
                uploaded[s] = missions, upload_route(m.links[s], missions, self.options.protocol,
                                                     limit=self.options.max_items)
            # the sortie stays awaited while it uploads: a vehicle falling silent on
            # the ground then is lost (and its work re-planned), not a failed flight
            if self._lost_or_failed(upload, [sysid], f"vehicle {sysid}'s next sortie upload",
                                    (InputError, MissionError)):
                continue
            parts.pop(0)
            self.swapped.discard(sysid)
            missions, mission = uploaded[sysid]
            m.new_mission(sysid, route, mission)
            self.segments.fly(sysid, missions)
            m.relaunch(sysid)
            self.offset[sysid] = offset
            self.departures[sysid] = Departure(offset + route.takeoff_s, "launch", route)
            m.event(sysid, f"sortie {route.waypoints[0].sortie} uploaded and verified",
                    items=len(mission), takeoff_s=round(offset + route.takeoff_s, 1))

    def _watch_batteries(self) -> None:
        """A vehicle whose battery will not last the rest of its sortie from where it
        is (`_left_s`) with half the plan's reserve kept is brought home early by its
        hidden path, its work re-planned; the reserve is there for smaller surprises
        (a landing queue). The draw is the rated one (the plan's endurance), or the
        rate drawn since takeoff where that is `FAST_DRAIN` times faster (its climbs
        allowed for, `CLIMB_S_PER_M`): such a
        battery is not trusted, and its vehicle is kept down until the crew has
        looked at it (its work going to the others). One slowed instead (holds, a
        headwind) is re-planned on the battery it reports, and flies on after a
        swap. A vehicle with nothing left to photograph is on its way home already."""
        endurance = self.plan.params.get("endurance_min")
        if not endurance:
            return                    # no battery model to hold the draw against
        rated = 100.0 / (60.0 * endurance)                  # % per fleet s
        m, reserve = self.monitor, float(self.plan.params.get("reserve_pct") or 0.0)
        rate = self.clock.rate()                            # fleet s per wall s
        short, untrusted = [], []
        for sysid, began in list(self._sortie_began.items()):
            v, state = m.vehicles[sysid], m.links[sysid].state
            pct, own, own0, pct0 = state.battery_pct, self._own_clock(sysid), began.own0, \
                began.pct0
            # on its own clock: a busy machine slows a simulator unevenly, and the
            # fleet's rate now is not the rate since takeoff (it once read 1.5 x the
            # rated draw on a vehicle drawing as rated)
            flown = own - own0 if None not in (own, own0) else (m.now() - began.t0) * rate
            if v.state not in (FLYING, HOLDING) or None in (pct0, pct) or \
                    flown < WATCH_AFTER_S or pct0 - pct < WATCH_AFTER_PCT:
                continue
            left_s = self._left_s(sysid)
            # the charge is timed by the vehicle's clock at the first report after it
            # (no later than that): it comes once a second, positions more often, and
            # at 100 x the last position before it can be 20 s older (a 2 x drain
            # timed by the last position read as 1.3 x, batteries drawing as rated
            # as 1.25 x); what it drew since is needed too
            by = state.battery_by_s
            drained_s = by - own0 if None not in (by, own0) else flown
            if left_s is None or drained_s <= 0:
                continue
            climbed = began.climb_to(m.vehicles[sysid].track, own0 + drained_s) \
                if own0 is not None else 0.0
            drawn = (pct0 - pct) / (rated * (drained_s + CLIMB_S_PER_M * climbed))
            fast = drawn > FAST_DRAIN
            since = max(0.0, flown - drained_s)
            rest = rated * (drawn if fast else 1.0) * (left_s + since)  # % the rest needs
            need = rest + reserve / 2
            if not began.forecast:
                began.forecast = True
                self._forecast(sysid, began, pct, pct0 - rated * began.flight_s, rest,
                               reserve, drawn if fast else None, flown)
            # a late one is re-planned once a sortie: a re-plan that cannot fit its
            # battery says so, and would only be made again
            if pct >= need or (not fast and sysid in self._late_acted):
                continue
            if self._homebound(sysid):      # nothing earlier to bring it to: said once
                if sysid not in self._late_acted:
                    self._late_acted.add(sysid)
                    m.event(sysid, f"battery {pct} % on its way home: the rest ({left_s / 60:.1f}"
                                   f" min at its pace) needs {rest:.0f} %, it will land on "
                                   f"about {pct - rest:.0f} % (less than half the reserve)")
                continue
            short.append(sysid)
            said = f"battery {pct} % will not last the rest of its sortie from where it is " \
                   f"({left_s / 60:.1f} min: {need:.0f} % with half the reserve, "
            if fast:
                untrusted.append(sysid)
                m.event(sysid, said + f"drawn {drawn:.1f} times faster than rated): "
                        "brought home early by its hidden path and kept down, its work "
                        "re-planned")
            else:
                late = self._late[sysid] = self._pace.get(sysid, 1.0)
                self._late_acted.add(sysid)
                m.event(sysid, said + f"at the rated draw, {late:.1f} times slower than "
                        "planned): brought home early by its hidden path, its work "
                        "re-planned on the battery it has at that pace")
        if short:
            for sysid in untrusted:
                del self._sortie_began[sysid]
            self.spent.update(untrusted)
            self.retask()

    def _forecast(self, sysid, began, pct, planned, rest, reserve, drawn, flown) -> None:
        """Say once a sortie, when its draw is first trusted, what the vehicle will land
        on at that draw from where it is (``rest``: % the rest of its sortie needs),
        beside what its plan said (``planned``, from the charge it took off with): the
        operator sees a battery that will not last before the watch has to act on it."""
        at = "the rated draw" if drawn is None else f"{drawn:.1f} times the rated draw"
        self.monitor.event(
            sysid, f"battery {pct} % after {flown / 60:.1f} min of sortie {began.sortie}: it "
                   f"will land on about {pct - rest:.0f} % at {at} (planned {planned:.0f} "
                   f"%, reserve {reserve:.0f} %)",
            landing_pct=round(pct - rest, 1), planned_pct=round(planned, 1))

    def _left_s(self, sysid):
        """Fleet seconds left in a vehicle's sortie from where it is (`_on_timeline`),
        stretched by how much slower than planned it has made its way along this
        route on its own clock (a headwind: never shrunk) since it last flew on from a
        hold (what a hold costs is in the battery it reports; a hold early on a route
        once read as 21 times slower; with the holds' spans taken out of its time
        instead, a simulated vehicle held at 100 x was once said to need 25.5 min,
        221 % of a battery, for the way home: a span's ends are known to a loop of
        the ground station, 10 s of its clock there, and its braking and speeding
        up again are in none); None past its last waypoint or without a
        position."""
        m = self.monitor
        v = m.vehicles[sysid]
        own = self._own_clock(sysid)
        at = self._on_timeline(sysid, own)
        if at is None:
            return None
        left = v.route.mission_time_s - at
        seen = self._route_seen.get(sysid)
        if seen is None or seen[0] is not v.route or v.state == HOLDING or \
                self._waiting_s(sysid) is not None:
            # its pace is timed from where it flies this route: not while a re-plan
            # holds it until its time (one so held read 6.8 times slower), nor while
            # the separation guard holds it
            self._route_seen[sysid] = (v.route, own, at)
            self._pace.pop(sysid, None)
            return left
        _, own0, at0 = seen
        if own - own0 >= WATCH_AFTER_S and at > at0:
            self._pace[sysid] = max(1.0, (own - own0) / (at - at0))
            left *= self._pace[sysid]
            self.paces.setdefault(sysid, {})[v.route.waypoints[0].sortie] = \
                round(self._pace[sysid], 3)
        return left

    def _on_timeline(self, sysid, own):
        """Where a vehicle is on its route's timeline (fleet s), None past its last
        waypoint or without a position: flying to its next waypoint, that one's
        planned arrival less the planner's leg time from here; standing at one its
        plan holds it at (the one it flies to or the one before: ArduPilot says it
        reached a waypoint before its hold, PX4 after), the arrival plus the time it
        has stood there, up to the hold (read as flying to the next, a 63 s hold
        timed a vehicle flying as planned 1.34 times slower)."""
        m = self.monitor
        v, state = m.vehicles[sysid], m.links[sysid].state
        waypoints = v.route.waypoints
        n = self._next_waypoint(sysid)
        if n >= len(waypoints) or state.lat is None or own is None:
            return None
        for w in (waypoints[i] for i in sorted({max(n - 1, 0), n})):
            if w.hold_s > 0 and _at_waypoint(w, state.lat, state.lon, state.alt_amsl):
                return w.t_s + min(w.hold_s, self._stood_s(sysid, w))
        w = waypoints[n]
        to_w = leg_time(distance_m(state.lat, state.lon, w.lat, w.lon),
                        w.alt_amsl - state.alt_amsl, self.ctx.scenario.travel_params())
        return w.t_s - float(to_w)

    def _stood_s(self, sysid, w) -> float:
        """Own-clock seconds the vehicle has stood at waypoint ``w``: back along its
        position reports to the first there."""
        track = self.monitor.vehicles[sysid].track
        since = track[-1][4]
        for _, lon, lat, alt, own in reversed(track):
            if not _at_waypoint(w, lat, lon, alt):
                break
            since = own
        return track[-1][4] - since

    def _next_waypoint(self, sysid) -> int:
        done = self.monitor.vehicles[sysid].done
        return max(done) + 1 if done else 0

    def _homebound(self, sysid) -> bool:
        """Nothing left to photograph: on its way home, where the watch has nothing
        earlier to bring it to."""
        waypoints = self.monitor.vehicles[sysid].route.waypoints
        return not any(w.snapshot for w in waypoints[self._next_waypoint(sysid):])

    def _own_clock(self, sysid):
        """The vehicle's own clock (s since its boot) at its last position report."""
        track = self.monitor.vehicles[sysid].track
        return track[-1][4] if track else None

    def _swapping(self) -> set:
        """Down at its base with a sortie to fly, its fresh battery not reported yet:
        a swap that powers the autopilot down silences it for a while."""
        m = self.monitor
        return {s for s in m.awaited() if m.vehicles[s].state == LANDED
                and not _fresh(m.links[s].state.battery_pct)}

    def _battery_ready(self, sysid, route, pct) -> bool:
        """The next sortie may go: the vehicle reports a fresh battery, and the
        operator confirmed the swap (`confirm_swap`) unless ``auto_turnaround``."""
        fresh = _fresh(pct)
        confirmed = self.options.auto_turnaround or sysid in self.swapped
        if fresh and confirmed:
            return True
        if self._waiting_battery.get(sysid) is not route:
            self._waiting_battery[sysid] = route
            why = [] if fresh else [f"a fresh battery ({pct} % reported)"]
            if not confirmed:
                why.append(f"the operator's word that it is swapped (type {sysid} and Enter, "
                           "or 'battery swapped' on the live map)")
            self.monitor.event(sysid, f"sortie {route.waypoints[0].sortie} waits for "
                               + " and ".join(why))
        return False

    def confirm_swap(self, sysid: int, where: str = "") -> bool:
        """The operator says vehicle ``sysid``'s battery is swapped (its next sortie may
        go once the battery it reports is fresh too); False for no such vehicle."""
        if sysid not in self.monitor.vehicles:
            return False
        self.swapped.add(sysid)
        self.monitor.event(sysid, "battery swap confirmed by the operator" + where)
        return True

    def swap_awaited(self, sysid: int) -> bool:
        """Down between two sorties, waiting for the operator's word on its battery."""
        return not self.options.auto_turnaround and sysid not in self.swapped and \
            sysid in self.monitor.awaited() and self.monitor.vehicles[sysid].state == LANDED

    def next_segments(self, sysids) -> None:
        """Send ``sysids`` their next segments; a loss meanwhile re-tasks the survivors
        (`watch` takes it next)."""
        m = self.monitor
        try:
            lost = self.segments.switch(sysids, lambda fn, s: _in_parallel(fn, s, m))
        except Exception as exc:       # a vehicle still heard from refused or failed
            raise FlightError(f"next segment failed: {exc}") from None
        if lost:
            m.event(None, "lost during a segment upload", lost=lost)

    def retask(self, home: bool = False) -> None:
        m = self.monitor
        try:
            ctx = self.context()
        except InputError as exc:
            raise FlightError(f"cannot re-plan: {exc}") from None
        m.event(None, "re-planning", survivors=m.survivors())
        if self.guard is not None:
            self.guard.forget()
        for sysid in list(self.departures):     # the re-plan decides who goes up
            del self.departures[sysid]
            m.call_off(sysid)   # a next sortie uploaded, its takeoff time not yet come
        self._call_off_starts()
        retasker = Retasker(ctx, m, self.mission_options, self.options.protocol,
                            segments=self.segments, depart=self.depart, spent=self.spent,
                            pace=self._late)
        try:
            record = retasker.retask(home)
        except RetaskError as exc:
            raise FlightError(str(exc)) from None
        # the re-plan covers what the later sorties would have: its own replace them
        now = self.clock.now() or 0.0
        self.later = {s: [(now, part) for part in parts]
                      for s, parts in retasker.later.items() if s in record.survivors}
        self.offset.update({s: now for s in record.survivors})
        if self.guard is not None:
            self.guard.priority.update(record.priority)
        for sysid, v in m.vehicles.items():     # never took off, and nothing to go up for
            if v.state == WAITING and sysid not in self.departures:
                m.set_state(sysid, LANDED)
                m.event(sysid, "stays on the ground: the re-plan has no task for it")
        self.retasks.append(record)

    # -- results ------------------------------------------------------------------------
    def report(self) -> dict:
        m = self.monitor
        vehicles = [self._vehicle_report(v) for _, v in sorted(m.vehicles.items())]
        losses = [{"sysid": v.sysid, "vehicle": v.vehicle_id, "detected_s": v.lost_at_s,
                   "last_heartbeat_s": v.last_heartbeat_s, "reason": v.lost_reason,
                   "stalled_s": v.lost_stalled_s}
                  for _, v in sorted(m.vehicles.items()) if v.state == LOST]
        coverage = self.coverage()
        return {
            "format": FORMAT, "plan": str(self.plan_dir),
            "started_utc": datetime.fromtimestamp(self.start_unix, timezone.utc).isoformat(),
            "start_unix": self.start_unix, "duration_s": round(m.now(), 3),
            "lost_after_s": self.options.lost_after_s, "k": int(self.plan.metrics.get("k", 0)),
            # what of the area of operations the plan's targets are, and its observers
            "area": self.plan.metrics.get("area"), "outposts": len(self.plan.outposts),
            "outcome": self.outcome(coverage),
            "vehicles": vehicles, "losses": losses,
            "replans": [asdict(r) for r in self.retasks],
            "segments": self.segments.report(),
            "separation": dict(self.guard.report() if self.guard is not None else {},
                               planned_closest_m=_finite_or_none(self.min_separation_m)),
            "coverage": coverage, "events": list(m.events),
        }

    def outcome(self, coverage: dict) -> dict:
        """Did the flight do its job? ``ok`` only with the required coverage reached
        (every coverable target seen by min(k + 1, survivors) survivors), no vehicle
        lost and none left in the air; ``problems`` says what went wrong, one line each."""
        m = self.monitor
        lost = [s for s, v in sorted(m.vehicles.items()) if v.state == LOST]
        stranded = [s for s, v in sorted(m.vehicles.items()) if v.state == STRANDED]
        # one whose start never came (or was called off) stands on the ground
        grounded = [s for s, v in sorted(m.vehicles.items()) if v.state == WAITING]
        flying = [s for s, v in sorted(m.vehicles.items())
                  if not v.finished and s not in grounded]
        survivors = coverage.get("survivors")
        reached = bool(survivors) and survivors["k_covered"] >= coverage["coverable_targets"]
        problems = []
        if self.error is not None:
            problems.append(f"failed: {self.error}")
        if lost:
            problems.append(f"vehicle(s) {', '.join(map(str, lost))} lost")
        if not reached:
            problems.append("required coverage not reached: " + (
                f"{survivors['k_covered']} of {coverage['coverable_targets']} coverable targets "
                f"seen by {survivors['required_uavs']} surviving vehicle(s)" if survivors
                else coverage.get("error", "no coverage computed")))
        if stranded:
            problems.append(f"vehicle(s) {', '.join(map(str, stranded))} stranded: held in "
                            "the air where no hidden leg joins them, left to the operator")
        held = sorted({a["sysid"] for a in (self.guard.actions if self.guard else [])
                       if a["action"] == "hold"})
        if held:
            problems.append(f"vehicle(s) {', '.join(map(str, held))} held by the separation "
                            "guard: flown off the proven schedule")
        for sysid, v in sorted(m.vehicles.items()):
            if v.off_route:
                worst = max(e[2] for e in v.off_route)
                problems.append(f"vehicle {sysid} flew off its proven route ({len(v.off_route)} "
                                f"time(s), up to {worst:.0f} m from its legs): what it flew "
                                "there was not proven hidden")
            if v.uncommanded:
                modes = ", ".join(f"{mode} at {t:.1f} s" for t, mode in v.uncommanded)
                problems.append(f"vehicle {sysid} flew in modes gcs did not command ({modes}): "
                                "what it flew there was not proven hidden")
        if flying:
            why = "timed out" if self.timed_out else (self.stopped or "stopped")
            problems.append(f"{why} with vehicle(s) {', '.join(map(str, flying))} in the air")
        if grounded:
            problems.append(f"vehicle(s) {', '.join(map(str, grounded))} never took off")
        return {"ok": not problems, "coverage_reached": reached, "lost": lost,
                "timed_out": self.timed_out, "in_air": sorted(flying + stranded),
                "stranded": stranded, "problems": problems}

    def _vehicle_report(self, v) -> dict:
        m = self.monitor
        return {
            "sysid": v.sysid, "vehicle": v.vehicle_id, "flavour": v.flavour, "state": v.state,
            "missions": v.generation + 1, "segments": v.segments,
            "mission_capacity": getattr(m.links.get(v.sysid), "mission_capacity", None),
            "lost_at_s": v.lost_at_s,
            "lost_reason": v.lost_reason, "landed_at_s": v.landed_at_s,
            "snapshots": [asdict(s) for s in v.snapshots],
            "camera": [list(c) for c in v.camera], "track": [list(p) for p in v.track],
            "off_route": [list(e) for e in v.off_route],
            "pace": {str(j): p for j, p in self.paces.get(v.sysid, {}).items()},
        }

    def coverage(self) -> dict:
        """k-coverage from the snapshots taken: by the survivors, and by every vehicle."""
        try:
            ctx = self.context()
        except Exception as exc:
            return {"error": str(exc)}
        m = self.monitor
        k = int(self.plan.metrics.get("k", ctx.scenario.k))
        alive = [v for _, v in sorted(m.vehicles.items()) if v.state != LOST]
        every = [v for _, v in sorted(m.vehicles.items())]
        # the targets only viewpoints beyond one battery see are not the flight's to cover
        short = int((self.plan.metrics.get("battery") or {}).get("targets_short", 0))
        out = {"coverable_targets": coverable_targets(ctx) - short,
               "beyond_battery_targets": short}
        for name, group in (("survivors", alive), ("all_vehicles", every)):
            out[name] = coverage_summary(ctx, [snapshot_xyz(ctx, v) for v in group], k)
        out["planned"] = {key: self.plan.metrics.get(key) for key in
                          ("targets", "covered", "k_covered", "coverage_time_s")}
        return out

    def write(self, report: dict) -> None:
        self.output.mkdir(parents=True, exist_ok=True)
        write_text_atomic(self.output / FLIGHT_FILE, json.dumps(report, indent=1))
        if self.options.plot:
            from gcs.flight_plot import flight_png
            try:
                ctx = self.context()
            except Exception:
                return
            flight_png(self.output / PLOT_FILE, ctx.terrain, ctx.surface, self.plan, report)

    def _on_event(self, entry) -> None:
        who = f"vehicle {entry['sysid']}: " if entry.get("sysid") is not None else ""
        extra = {k: v for k, v in entry.items() if k not in ("t_s", "sysid", "event")}
        tail = " " + " ".join(f"{k}={v}" for k, v in extra.items()) if extra else ""
        self.log(f"[{entry['t_s']:8.1f} s] {who}{entry['event']}{tail}")


def fly(plan_dir, urls, options: FlyOptions = None, log=None, status=None,
        on_interrupt=None, on_timeout=None, ctx=None) -> dict:
    """Fly ``plan_dir`` on the vehicles at ``urls``; returns the flight report.
    ``ctx``: the plan's context when it is in memory (else read from the folder)."""
    return Flight(plan_dir, urls, options or FlyOptions(), log, ctx).run(status, on_interrupt,
                                                                          on_timeout)


__all__ = ["Flight", "FlightError", "FlyOptions", "LANDED", "LOST", "assign_vehicles", "fly"]
