# Over 600 lines, knowingly: one Monitor owns each vehicle's telemetry state (progress,
# snapshots, silence, liftoff, landing), and every verdict reads the same fields under one lock.
"""Following each vehicle from its telemetry: progress, snapshots, losses, landing.

A `Monitor` subscribes to every `gcs.link.VehicleLink` of the flight. From the
reader threads it records the track (GLOBAL_POSITION_INT), the mission items
reached (MISSION_ITEM_REACHED, mapped to plan waypoints through
`VehicleMission.waypoint_of_item`; an item reached means every waypoint before it
was, as PX4 reports a waypoint followed by DO commands with the number of the last
of them, and only the latest of several reached between two reports) and camera
feedback. A snapshot counts as
taken when its waypoint is reached: ArduPilot reports MISSION_ITEM_REACHED for
navigation items only, and camera feedback only with a camera configured, so
the waypoint is the one signal every autopilot gives. Camera feedback, where
it comes, is kept beside it.

Loss detection (`check_losses`, on the wall clock, by the flight loop and by a
thread of its own while the flight computes or waits: `watch_losses`):
a vehicle is lost when nothing (no HEARTBEAT, no report) has come for
``lost_after_s`` seconds,
or when it disarms in the air. A link that comes back earlier is not a loss.
A silence that starts where the plan predicts a radio shadow (`gcs.contact`) is
an event, out of contact as planned; the vehicle is lost only when it is not heard
by the shadow's end at its measured pace, with a margin (overdue).

A vehicle in the air further from its route's proven legs than the plan's track
tolerance (`gcs.corridor`) flies where nothing was proven: an event when it
leaves them and when it is back, and an episode in ``off_route``.

Touching the ground is a landing only at a base of its flight (the launch point,
or the base a sortie lands at) after the mission's last waypoint (the one above
that base, before the landing). Anywhere else, or earlier, it is a crash: the
vehicle is lost with its snapshots. So is a vehicle whose altitude goes below
the terrain (the plan's DEM) + ``CRASH_MARGIN_M`` away from its bases, whether
or not it disarms.
"""

import collections
import math
import re
import threading
import time
from dataclasses import dataclass, field

import numpy as np

from common.geo import distance_m
from gcs.contact import Contact, Expected
from gcs.corridor import POSITION_MARGIN_M, ProvenPath
from gcs.link import has_position
from gcs.mavlink import M
from missions.items import NAV_LAND
from missions.returns import landing_gaps

# Flight states of a vehicle, as shown in the status table and flight.json.
WAITING, STARTING, FLYING, HOLDING, RETURNING, LANDED, LOST = (
    "waiting", "starting", "flying", "holding", "returning", "landed", "lost")
#: held in the air where no hidden leg joins it to the hidden volume (a re-plan
#: cannot route it): left to the operator, still watched for a loss
STRANDED = "stranded"
#: below this height above home (m) a disarmed vehicle has landed, above it it fell
LANDED_AGL_M = 3.0
#: this high above home (m), armed, a vehicle has left the ground: its liftoff as it
#: reports it, which a fleet's takeoffs are timed on (seconds after the command that
#: sent it up, with arming and spool-up: `gcs.flight.departures`)
LIFTOFF_M = 1.0
#: keep one track sample per this many wall seconds (telemetry comes at a few Hz)
TRACK_PERIOD_S = 0.2
#: position reports above LANDED_AGL_M after a disarm that make it a fall
DISARM_REPORTS = 3
#: within this distance (m, horizontally) of its launch point a touchdown is a landing
LAUNCH_RADIUS_M = 10.0
#: a vehicle is started (or re-launched) only within the plan's track tolerance of its
#: launch point, and at least this (m: a GNSS fix on the ground)
MIN_LAUNCH_TOLERANCE_M = 1.0
#: below the terrain + this (m) away from its launch point, a vehicle has hit the ground
CRASH_MARGIN_M = 2.0
#: wall seconds a vehicle down for its battery swap may be silent (most flight
#: controllers are fed by the pack: a swap powers them down) before it is lost: the
#: crew's swap and the autopilot's boot (`gcs fly --swap-silence`)
SWAP_SILENCE_S = 600.0
#: wall seconds a held vehicle is given to brake before its position is taken
SETTLE_S = 3.0
SETTLED_MPS = 0.5



def _uncommanded_said(profile, mode: str) -> str:
    """The event of a flying vehicle seen in ``mode``, which gcs did not command: a
    failsafe's mode (the profile's ``failsafe_modes``) says what the firmware flies
    in it."""
    flies = profile.failsafe_modes.get(mode)
    if flies is not None:
        return (f"failsafe: flying in {mode}, a mode gcs did not command ({flies}): the "
                "autopilot's own action, proven hidden only where `gcs fly` found its "
                "failsafes hidden")
    return (f"flying in {mode}, a mode gcs did not command (a pilot's or a failsafe's): "
            "what it flies there is not proven hidden")

def _own_at(state, mono: float) -> float | None:
    """A vehicle's own clock (s since boot) at ``mono`` (time.monotonic()): its latest
    report's, carried on at its clock's rate; None unknown."""
    boot_s, boot_at = getattr(state, "boot_s", None), getattr(state, "boot_at", None)
    if boot_s is None or boot_at is None:
        return None
    return boot_s + (mono - boot_at) * getattr(state, "clock_rate", 1.0)


def mission_items(mission) -> int:
    """Items of ``mission`` (0 for None): by its len() where it has one, as a checked
    mission does, whose ``items`` are copies made on each read (the status line's
    read of them was a tenth of the flight loop's time)."""
    if mission is None:
        return 0
    return len(mission) if hasattr(mission, "__len__") else len(mission.items)


def _or_dash(value) -> str:
    return "-" if value is None else str(value)


def shown_item(state, items: int) -> int | None:
    """The item of its current mission (``items`` long) a vehicle reports flying, for
    the operator; None before it reports one: a MISSION_CURRENT of the mission before
    still on its way names an item past this one's end (a relaunched vehicle shown
    at "item 70/49")."""
    seq = getattr(state, "mission_seq", None)
    return int(seq) if seq is not None and 0 <= seq < items else None


def _note_airborne(v, armed: bool, agl) -> None:
    """Armed away from home height, above it or below it (a route over lower ground
    than the launch point): flying. Judged on every position report too: at a high
    speed-up a heartbeat may come only after the vehicle has dropped below home."""
    if armed and agl is not None and abs(agl) > LANDED_AGL_M:
        v.airborne = True


def _speed(state, vertical: bool) -> float:
    """m/s from the last GLOBAL_POSITION_INT: ground speed, or 3-D with ``vertical``."""
    if vertical and state.velocity is not None:
        return math.hypot(*state.velocity)
    return math.inf if state.groundspeed is None else state.groundspeed


@dataclass
class Snapshot:
    t_s: float  # seconds since the flight started (wall clock)
    lon: float
    lat: float
    alt_amsl: float
    mission: int  # which mission of the vehicle: 0 = the plan, 1.. = re-plans
    waypoint: int  # index into that mission's route waypoints


@dataclass
class VehicleProgress:
    """What the ground station knows about one vehicle of the flight."""

    sysid: int
    vehicle_id: int  # plan route id
    flavour: str
    route: object  # planner.plan.VehicleRoute being flown
    mission: object  # missions.build.VehicleMission uploaded
    generation: int = 0  # 0: the plan's mission; n: the n-th re-plan
    state: str = WAITING
    reached: set = field(default_factory=set)  # item seqs reached in this mission
    done: set = field(default_factory=set)  # route waypoint indices reached in this mission
    snapshots: list = field(default_factory=list)  # [Snapshot], every mission
    camera: list = field(default_factory=list)  # camera feedback positions [(t, lon, lat, alt)]
    track: list = field(default_factory=list)  # [(t, lon, lat, alt AMSL, vehicle time s)]
    airborne: bool = False
    lifted_at_s: float | None = None  # when it last left the ground (`LIFTOFF_M`)
    return_gaps: list = field(default_factory=list)  # said of its mission's return, last
    lost_at_s: float | None = None
    lost_reason: str | None = None
    lost_stalled_s: float = 0.0  # of its silence, the time this ground station stood still
    last_heartbeat_s: float | None = None
    landed_at_s: float | None = None
    disarmed_at_s: float | None = None  # disarmed after flying: landed or fell?
    disarmed_reports: int = 0  # position reports since
    relaunched: int = 0  # times sent up again after landing
    grounded: str = WAITING  # its state before the re-launch under way (`call_off`)
    segments: int = 0  # segments sent in flight (a route longer than the vehicle holds)
    uncommanded: list = field(default_factory=list)  # [(t_s, mode)] flown in, not commanded
    proven: object = None  # gcs.corridor.ProvenPath of the route flown now
    off_route: list = field(default_factory=list)  # [[from t_s, to t_s or None, max m]]
    powered_down_at_s: float | None = None  # silent at its base for a battery swap since
    # its predicted radio shadows, on this monitor's clock (`follow`: its route's)
    contact: Contact = field(default_factory=lambda: Contact([]))
    quiet: Expected | None = None  # the predicted silence it is in now, if heard silent
    quiet_flown: float = 0.0  # of it, fleet seconds of its plan flown since heard (estimated)
    quiet_at: float = 0.0  # when that was last counted (monitor s)
    silences: list = field(default_factory=list)  # [{"from_s", "to_s", "due_s", ...}] flown
    heard_after_loss_s: float | None = None  # its first HEARTBEAT after it was declared lost
    silent_loss: bool = False  # declared lost for a silence (may come back), not a crash
    rejoins: list = field(default_factory=list)  # [{"lost_at_s", "reason", "back_s", ...}]
    _trajectory: tuple = (None, None)  # (route, its trajectory array): `trajectory`

    @property
    def snapshot_total(self) -> int:
        return sum(1 for w in self.route.waypoints if w.snapshot)

    @property
    def snapshots_done(self) -> int:
        """Snapshots of the current mission taken so far."""
        return sum(1 for i in self.done if self.route.waypoints[i].snapshot)

    @property
    def trajectory(self):
        """Its route's planned trajectory as an array [t_s, lon, lat, alt AMSL] (None
        without one), made once per route: read on every loop of the flight."""
        if self._trajectory[0] is not self.route:
            rows = getattr(self.route, "trajectory", None)
            self._trajectory = (self.route, np.asarray(rows, float) if rows else None)
        return self._trajectory[1]

    @property
    def finished(self) -> bool:
        """Nothing more for the flight to do with it (a stranded one is the operator's)."""
        return self.state in (LANDED, LOST, STRANDED)

    @property
    def bases(self) -> list:
        """[(lat, lon)] of where its flight takes off and lands: its route's launch
        point, and the base a sortie lands at when that is another."""
        points = [getattr(self.route, "launch", None), getattr(self.route, "land", None)]
        return [(p.lat, p.lon) for p in points if p is not None]

    def final_approach_seq(self) -> int | None:
        """The mission item a proper landing comes after: the last waypoint (above
        launch) before the final NAV_LAND, or the last position item."""
        items = getattr(self.mission, "items", None) or []
        if not getattr(self.mission, "final", True):
            return len(items)           # a segment that does not land: no touchdown is one
        positions = [it.seq for it in items if it.is_position]
        if not positions:
            return None
        if items[positions[-1]].command == NAV_LAND and len(positions) > 1:
            return positions[-2]
        return positions[-1]


class StallClock:
    """How long this ground station itself stood still: a thread that wakes every
    `PERIOD_S` records each gap longer than that (the process starved of CPU by a
    busy machine, or held by a long computation). Silence heard while the ground
    station was not listening is no evidence that a vehicle is gone."""

    PERIOD_S = 0.05
    KEPT = 4096          # gaps remembered (the oldest are dropped)

    def __init__(self):
        self._gaps = collections.deque(maxlen=self.KEPT)    # (start, end), monotonic
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="stall-clock", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        last = time.monotonic()
        while not self._stop.wait(self.PERIOD_S):
            now = time.monotonic()
            if now - last > 2 * self.PERIOD_S:
                self._gaps.append((last + self.PERIOD_S, now))
            last = now

    def stalled(self, since: float) -> float:
        """Seconds since monotonic time ``since`` this process did not run."""
        return sum(max(0.0, end - max(start, since)) for start, end in list(self._gaps)
                   if end > since)

    def stop(self) -> None:
        self._stop.set()


class Monitor:
    """Telemetry of every vehicle of a flight, on one clock (seconds since `t0`)."""

    def __init__(self, lost_after_s: float = 5.0, on_event=None, ground=None,
                 track_tolerance_m=None):
        """``ground(lat, lon)``: terrain altitude (m AMSL; NaN outside) of the plan's
        DEM, to tell a vehicle that went below it; ``track_tolerance_m``: the room
        the plan's legs are proven with, to tell a vehicle off them; None: not judged."""
        self.lost_after_s = float(lost_after_s)
        self.ground = ground
        self.track_tolerance_m = track_tolerance_m
        self.stalls = StallClock()
        self.awaited = set     # () -> sysids landed with a sortie still to fly (`Flight`)
        self.swapping = set    # () -> of them, down at base, their battery swap not yet seen
        self.swap_silence_s = SWAP_SILENCE_S
        self.t0 = time.monotonic()
        self.vehicles = {}  # sysid -> VehicleProgress
        self.links = {}  # sysid -> VehicleLink
        self.events = []  # [{"t_s", "sysid", "event", ...}]
        self._lock = threading.RLock()
        self._untaken = []  # lost vehicles not yet taken by the flight (`take_losses`)
        self._rejoined = []  # vehicles taken back after a loss, not yet re-planned for
        self._unsubscribe = []
        self._on_event = on_event
        self._watching = None  # the event that stops `watch_losses`

    def now(self) -> float:
        return time.monotonic() - self.t0

    # -- setting up -----------------------------------------------------------------
    def follow(self, link, vehicle_id: int, route, mission) -> VehicleProgress:
        """Start following vehicle ``link`` flying ``route`` as ``mission`` (again, from
        the start: a vehicle on the ground given another plan)."""
        progress = VehicleProgress(link.sysid, vehicle_id, link.flavour, route, mission)
        progress.proven = ProvenPath(route)
        progress.contact = Contact(route.silences, trajectory=route.trajectory)
        with self._lock:
            known = link.sysid in self.links
            self.vehicles[link.sysid] = progress
            self.links[link.sysid] = link
        if not known:
            self._unsubscribe.append(link.subscribe(lambda msg, s=link.sysid: self._on(s, msg)))
        return progress

    def watch_losses(self, period_s: float = 0.2) -> None:
        """`check_losses` every ``period_s`` on a thread of its own until `close`: a
        loss is found on time even while the flight computes (a re-plan takes
        seconds on a busy machine) or waits on other vehicles."""
        if self._watching is not None:
            return
        self._watching = threading.Event()
        stop = self._watching

        def run():
            while not stop.wait(period_s):
                self.check_losses()
        threading.Thread(target=run, name="loss-watch", daemon=True).start()

    def close(self) -> None:
        if self._watching is not None:
            self._watching.set()
        for unsubscribe in self._unsubscribe:
            unsubscribe()
        self._unsubscribe = []
        self.stalls.stop()

    def event(self, sysid, text: str, **extra) -> dict:
        entry = {"t_s": round(self.now(), 3), "sysid": sysid, "event": text, **extra}
        with self._lock:
            self.events.append(entry)
        if self._on_event is not None:
            self._on_event(entry)
        return entry

    def set_state(self, sysid: int, state: str) -> None:
        """Move to ``state``; LANDED and LOST are final (a landed vehicle is not re-launched)."""
        with self._lock:
            v = self.vehicles[sysid]
            if v.state != state and not v.finished:
                v.state = state
                self.event(sysid, state)

    def new_mission(self, sysid: int, route, mission, fleet_s: float = 0.0) -> None:
        """The vehicle now flies ``mission`` (a re-plan, a next sortie): progress restarts
        at its item 1. One in the air is at ``fleet_s`` of ``route``'s clock now: 0
        where it is held until its ``takeoff_s`` (marked there, a silence soon after it
        flew on was read that hold's length ahead of its plan). One down at a base is
        on no clock until its liftoff marks it: marked now, its wait for its takeoff
        read as slow flight (at 150x, 2 wall s in a base column's queue halved its
        pace, and its first shadow was not matched: a loss)."""
        with self._lock:
            v = self.vehicles[sysid]
            s = self.links[sysid].state
            held = (s.lat, s.lon, s.alt_amsl) if v.airborne and s.lat is not None else None
            v.route, v.mission, v.proven = route, mission, ProvenPath(route, held)
            v.generation += 1
            v.reached, v.done = set(), set()
            v.contact.restart(route.silences, route.trajectory)
            if v.airborne and v.state != LANDED:    # airborne stays set until relaunched
                # placed, not timed: a hold until its time is not flight
                v.contact.mark(self.now(), fleet_s, self._own_clock(v), timed=False)
            self.links[sysid].state.mission_seq = None   # the old mission's; wait for news
        self._return_gaps(sysid, mission)

    def set_mission(self, sysid: int, mission) -> None:
        """The mission uploaded for the current route (the whole, or its first segment)."""
        with self._lock:
            self.vehicles[sysid].mission = mission
        self._return_gaps(sysid, mission)

    def _return_gaps(self, sysid: int, mission) -> None:
        """Where the firmware's return along ``mission`` would leave the proven legs
        (`missions.returns.landing_gaps`: PX4's Return along a mission that does not
        land at a base, or does not start above its home), said as a known risk when
        it changes: a segment or a re-task flown in the air has them all along."""
        v = self.vehicles[sysid]
        gaps = landing_gaps(mission) if getattr(mission, "firmware", None) else []
        if gaps and gaps != v.return_gaps:
            self.event(sysid, "known risk: its Return along this mission: " + "; ".join(gaps),
                       return_gaps=gaps)
        v.return_gaps = gaps

    def next_segment(self, sysid: int, mission, counted: bool = True) -> None:
        """The vehicle now flies the next segment of the same route (``counted``), or
        the rest of its segment uploaded again: item numbers start again, the
        waypoints reached and snapshots taken stay."""
        with self._lock:
            v = self.vehicles[sysid]
            v.mission = mission
            v.reached = set()
            v.segments += 1 if counted else 0
            self.links[sysid].state.mission_seq = None
        self._return_gaps(sysid, mission)

    def relaunch(self, sysid: int) -> None:
        """A landed survivor (or one still waiting for its takeoff) goes up on a
        re-plan's route."""
        with self._lock:
            v = self.vehicles[sysid]
            if v.state not in (LANDED, WAITING):
                return
            v.grounded, v.state, v.airborne = v.state, STARTING, False
            v.disarmed_at_s, v.disarmed_reports, v.lifted_at_s = None, 0, None
            v.relaunched += 1
            self.event(sysid, "re-launching")

    def call_off(self, sysid: int) -> None:
        """A start called off before the vehicle left the ground (a re-plan takes
        the fleet over): it is again what it was, down at its base; never a vehicle
        "flying" there, which a re-plan would hold and send on from the ground."""
        with self._lock:
            v = self.vehicles[sysid]
            if v.state == STARTING and not v.airborne:
                v.state = v.grounded
                self.event(sysid, f"start called off: {v.state}")

    # -- telemetry (reader threads) ---------------------------------------------------
    def _on(self, sysid: int, msg) -> None:
        kind = msg.get_type()
        handler = self._HANDLERS.get(kind)
        if handler is not None:
            with self._lock:
                v = self.vehicles.get(sysid)
                if v is not None and v.state != LOST:
                    handler(self, v, msg)
                elif v is not None and kind == "HEARTBEAT" and v.heard_after_loss_s is None:
                    v.heard_after_loss_s = round(self.now(), 3)
                    self.event(sysid, f"heard again after it was declared lost ({v.lost_reason})"
                               + ("" if v.silent_loss else ": it came down where it is not "
                                  "flown or guarded by this flight; bring it home by hand"),
                               heard_after_loss=True)

    def _heartbeat(self, v, msg) -> None:
        v.last_heartbeat_s = self.now()
        if v.quiet is not None:
            self._back_in_contact(v)
        armed = bool(msg.base_mode & M.MAV_MODE_FLAG_SAFETY_ARMED)
        agl = self.links[v.sysid].state.relative_alt
        _note_airborne(v, armed, agl)
        if v.airborne and armed:
            self._judge_mode(v)
        if v.airborne and not armed and v.state != LANDED and v.disarmed_at_s is None:
            # position reports lag the touchdown: judge by the next ones
            v.disarmed_at_s = self.now()
            v.disarmed_reports = 0
            self._judge_disarm(v, agl)

    def _judge_mode(self, v) -> None:
        """In the air in a mode the ground station did not command (a pilot took
        over, a failsafe fired: RTL, LAND): what it flies now is not proven hidden.
        Each such mode is an event and a problem of the flight (`uncommanded`)."""
        link = self.links[v.sysid]
        profile = getattr(link, "profile", None)
        mode = link.state.mode
        if profile is None or mode is None or mode in profile.commanded_modes:
            return
        if not v.uncommanded or v.uncommanded[-1][1] != mode:
            v.uncommanded.append((round(self.now(), 3), mode))
            self.event(v.sysid, _uncommanded_said(profile, mode))

    def _judge_disarm(self, v, agl) -> None:
        """Disarmed after flying: on the ground or still falling? On the ground it
        landed only at a base of its flight after its last waypoint; anywhere else,
        or before, it crashed (lost)."""
        s = self.links[v.sysid].state
        height = self._height(s)
        touched = (agl is not None and abs(agl) <= LANDED_AGL_M) or \
            (height is not None and height <= LANDED_AGL_M) or getattr(s, "landed", None) is True
        if not touched:
            if v.disarmed_reports >= DISARM_REPORTS:
                self._lose(v, f"disarmed in the air ({agl or 0.0:.0f} m above home)")
            return
        away = self._from_base(v, s)
        if away is not None and away > LAUNCH_RADIUS_M:
            return self._lose(v, self._down_said(v, away) or
                              f"crashed: touched the ground {away:.0f} m from its base")
        final, progress = v.final_approach_seq(), self._progress(v, s)
        if final is not None and (progress is None or progress < final) and \
                not self._failsafe_return(v):
            where = "nothing" if progress is None else f"item {progress}"
            return self._lose(v, f"crashed: touched the ground before its last item "
                                 f"({where} of {final} reached)")
        v.state = LANDED
        v.landed_at_s = round(self.now(), 3)
        self.event(v.sysid, LANDED, battery_pct=s.battery_pct)

    def _on_ground(self, s) -> bool:
        """By its height above the plan's terrain, fresh with its position; without a
        terrain by its own word (EXTENDED_SYS_STATE), else by its height above home,
        which is no height above the ground: a route over a valley flies at home
        height (a vehicle heard back there was once judged down in the field)."""
        height = self._height(s)
        if height is not None:
            return height <= LANDED_AGL_M
        if getattr(s, "landed", None) is not None:
            return s.landed
        agl = getattr(s, "relative_alt", None)
        return agl is not None and abs(agl) <= LANDED_AGL_M

    def _height(self, s):
        """Height (m) above the plan's terrain, None when unknown."""
        if self.ground is None or getattr(s, "lat", None) is None or s.alt_amsl is None:
            return None
        ground = self.ground(s.lat, s.lon)
        return None if ground is None or not math.isfinite(ground) else s.alt_amsl - ground

    def in_failsafe(self, sysid) -> bool:
        """Flying in a failsafe's mode now (SmartRTL, RTL, LAND): the autopilot's own
        return, which no command of the ground station should undo."""
        link = self.links.get(sysid)
        modes = getattr(getattr(link, "profile", None), "failsafe_modes", {})
        return link is not None and link.state.mode in modes

    def _failsafe_return(self, v) -> bool:
        """Its last mode was a failsafe's (SmartRTL, RTL, LAND): down at a base before
        its last item, it came home on the autopilot's own; elsewhere, it is down in
        the field (lost to the flight all the same), not crashed."""
        modes = getattr(getattr(self.links.get(v.sysid), "profile", None), "failsafe_modes", {})
        return bool(v.uncommanded) and v.uncommanded[-1][1] in modes

    def _down_said(self, v, away) -> str | None:
        """A vehicle a failsafe put down away from its bases: why it is lost to the
        flight (None when no failsafe did)."""
        if not self._failsafe_return(v):
            return None
        return (f"down in the field: a failsafe's {v.uncommanded[-1][1]} put it on the ground "
                f"{away or 0.0:.0f} m from its base")

    @staticmethod
    def _from_base(v, s):
        """Horizontal distance (m) from the nearer of its bases (`Vehicle.bases`: the
        launch point, the base a sortie lands at; home where the route has none)."""
        home = getattr(s, "home", None)
        bases = v.bases or ([home[:2]] if home is not None else [])
        if not bases or getattr(s, "lat", None) is None:
            return None
        return min(distance_m(b[0], b[1], s.lat, s.lon) for b in bases)

    @staticmethod
    def _progress(v, s):
        """The furthest item of the current mission the vehicle is known to have
        reached or be flying to (MISSION_ITEM_REACHED, MISSION_CURRENT)."""
        seen = set(v.reached)
        if getattr(s, "mission_seq", None) is not None:
            seen.add(int(s.mission_seq))
        return max(seen) if seen else None

    def _below_terrain(self, v, s) -> None:
        """Away from launch and below the terrain + CRASH_MARGIN_M: it hit the ground."""
        height = self._height(s)
        if height is None or height >= CRASH_MARGIN_M:
            return
        away = self._from_base(v, s)
        if away is None or away > LAUNCH_RADIUS_M:
            self._lose(v, self._down_said(v, away) or f"crashed: {height:.1f} m above the "
                          f"terrain ({s.alt_amsl:.1f} m AMSL, {away or 0.0:.0f} m from launch)")

    def _position(self, v, msg) -> None:
        if not has_position(msg):
            return                     # no position yet (ArduPilot before its EKF origin)
        t = self.now()
        agl = msg.relative_alt * 1e-3
        armed = self.links[v.sysid].state.armed
        _note_airborne(v, armed, agl)
        if armed and agl > LIFTOFF_M and v.lifted_at_s is None:
            v.lifted_at_s = t
            if not v.done:          # the route's takeoff: its first progress on the fleet clock
                v.contact.mark(t, getattr(v.route, "takeoff_s", 0.0), self._own_clock(v),
                               timed=False)     # seen once its HEARTBEAT says it armed
        if v.airborne and v.state not in (LANDED, LOST):
            self._below_terrain(v, self.links[v.sysid].state)
            if v.state == LOST:
                return
            if v.state != STRANDED:
                self._judge_route(v, msg.lat * 1e-7, msg.lon * 1e-7, msg.alt * 1e-3, t)
        if v.disarmed_at_s is not None and v.state != LANDED:
            v.disarmed_reports += 1
            self._judge_disarm(v, agl)
        if v.track and t - v.track[-1][0] < TRACK_PERIOD_S:
            return
        # the vehicle's own clock too: mission time, which runs faster than the wall
        # clock in a sped-up simulation
        boot = getattr(msg, "time_boot_ms", None)
        v.track.append((round(t, 3), msg.lon * 1e-7, msg.lat * 1e-7, msg.alt * 1e-3,
                        None if boot is None else round(boot * 1e-3, 3)))
        # its clock's rate (a sped-up simulator, slower on a busy machine), as its link
        # measures it
        if boot is not None:
            v.contact.set_clock_rate(getattr(self.links[v.sysid].state, "clock_rate", 1.0))

    def _judge_route(self, v, lat, lon, alt, t) -> None:
        """Off its proven legs (beyond the track tolerance and the position's own
        error) or back on them: an event each time, the episode kept."""
        if self.track_tolerance_m is None or v.proven is None:
            return
        d = v.proven.distance_m(lat, lon, alt)
        off = v.off_route[-1] if v.off_route and v.off_route[-1][1] is None else None
        if d > self.track_tolerance_m + POSITION_MARGIN_M:
            if off is None:
                v.off_route.append([round(t, 3), None, round(d, 1)])
                self.event(v.sysid, f"{d:.0f} m off its proven route (its legs are proven "
                                    f"with {self.track_tolerance_m:g} m of room): what it "
                                    "flies there is not proven hidden")
            else:
                off[2] = max(off[2], round(d, 1))
        elif off is not None:
            off[1] = round(t, 3)
            self.event(v.sysid, f"back on its proven route after {t - off[0]:.1f} s, "
                                f"{off[2]:.0f} m off at most")

    def _reached(self, v, msg) -> None:
        """An item reached: its waypoint, and every waypoint of the mission before it
        not counted yet, since a mission is flown in order. PX4 reports a waypoint
        followed by DO commands (the camera) once they are done, with the last
        one's number, and only the latest item reached when several are reached
        between two of its reports (close waypoints)."""
        seq = int(msg.seq)
        if seq in v.reached:
            return
        v.reached.add(seq)
        self._passed(v, seq, timed=True)

    def _passed(self, v, seq: int, timed: bool) -> None:
        """Item ``seq`` passed, and so every waypoint before it; only a reached item
        reported now is ``timed`` (measured on, for the vehicle's pace)."""
        of_item = v.mission.waypoint_of_item
        passed = []
        for item in range(min(seq, len(of_item) - 1), -1, -1):
            index = of_item[item]
            if index is None:
                continue
            if index in v.done:
                break                   # counted, and so is everything before it
            passed.append(index)
        for index in reversed(passed):
            v.done.add(index)
            w = v.route.waypoints[index]
            # only the one reported was reached now; those before it, passed unheard
            # (in a shadow), were reached earlier: timed now they read as a burst
            v.contact.mark(self.now(), w.t_s, self._own_clock(v),
                           timed=timed and index == passed[0])
            if w.snapshot:
                v.snapshots.append(Snapshot(round(self.now(), 3), w.lon, w.lat, w.alt_amsl,
                                            v.generation, index))

    def _camera(self, v, msg) -> None:
        if msg.get_type() == "CAMERA_FEEDBACK":
            lat, lon, alt = msg.lat * 1e-7, msg.lng * 1e-7, msg.alt_msl
        else:
            lat, lon, alt = msg.lat * 1e-7, msg.lon * 1e-7, msg.alt * 1e-3
        v.camera.append((round(self.now(), 3), lon, lat, alt))

    def _text(self, v, msg) -> None:
        """A STATUSTEXT in which the autopilot says a failsafe fired or its return is
        gone (the profile's ``failsafe_texts``): an event, in its words."""
        profile = getattr(self.links.get(v.sysid), "profile", None)
        pattern = getattr(profile, "failsafe_texts", None)
        text = str(getattr(msg, "text", ""))
        if pattern and re.search(pattern, text):
            self.event(v.sysid, f"failsafe: the autopilot says \"{text}\"")

    _HANDLERS = {"HEARTBEAT": _heartbeat, "GLOBAL_POSITION_INT": _position,
                 "MISSION_ITEM_REACHED": _reached, "CAMERA_FEEDBACK": _camera,
                 "CAMERA_IMAGE_CAPTURED": _camera, "STATUSTEXT": _text}

    # -- losses (flight loop) ---------------------------------------------------------
    def wait_settled(self, sysids, vertical: bool = True, timeout_s: float = SETTLE_S) -> None:
        """Give held vehicles time to brake before their positions are taken: until
        each reports moving slower than `SETTLED_MPS` (with ``vertical`` in 3-D: one
        still sinking is not where it will stand), ``timeout_s`` wall seconds at
        most; losses are looked for meanwhile (found by the caller's next step)."""
        end = time.monotonic() + timeout_s
        time.sleep(0.3)                 # the hold on its way, and a report after it
        while time.monotonic() < end:
            self.check_losses()
            if all(_speed(self.links[s].state, vertical) < SETTLED_MPS for s in sysids):
                return
            time.sleep(0.1)

    def check_losses(self) -> list:
        """Vehicles newly found lost: silent for ``lost_after_s`` (wall clock), in the
        air or landed with work still to fly (`awaited`: its next sortie); down at
        its base for a battery swap not yet seen (`swapping`), for ``swap_silence_s``:
        the swap powers most autopilots down. Each is also kept for `take_losses`,
        whoever called this."""
        lost = []
        awaited, swapping = self.awaited(), self.swapping()
        with self._lock:
            for sysid, v in self.vehicles.items():
                if v.state == LOST and self._heard_back(v):
                    self._rejoin(v)
                if v.finished and v.state != STRANDED and \
                        not (v.state == LANDED and sysid in awaited):
                    if v.state == LOST and v.lost_at_s is not None and not getattr(
                            v, "_reported", False):
                        v._reported = True
                        lost.append(sysid)
                    continue
                age, stalled = self._silence(sysid)
                swap = sysid in swapping
                self._note_power(v, age - stalled, swap)
                silent = age - stalled > self.lost_after_s
                if silent and not swap and self._as_planned(v, age):
                    continue
                if v.quiet is not None:     # heard again: its HEARTBEAT handler says so
                    if silent:
                        self._lose_overdue(v)
                        lost.append(sysid)
                    continue
                if age - stalled > (max(self.swap_silence_s, self.lost_after_s) if swap
                                    else self.lost_after_s):
                    v.lost_stalled_s = round(stalled, 3)
                    self._lose(v, f"nothing heard for {age:.1f} s"
                                  + (" since it landed for its battery swap" if swap else ""),
                               silence=True)
                    v._reported = True
                    lost.append(sysid)
            self._untaken.extend(lost)
        return lost

    def _as_planned(self, v, age) -> bool:
        """A silence inside a predicted radio shadow, not yet overdue: said once (out of
        contact, as planned, and when it is due back), not a loss. Only in the air: the
        plan predicts no silence on the ground (a vehicle silent at its base for its
        next sortie's upload once read as a shadow of that sortie, and was never lost)."""
        if v.quiet is None:
            # airborne stays set until relaunched; a held vehicle hovers where it was
            # heard, off its plan's clock (placed along its plan, one held for a
            # re-plan was taken into a shadow it never flew, and not lost)
            if not v.airborne or v.state in (LANDED, HOLDING):
                return False
            s = self.links[v.sysid].state
            lat, lon = getattr(s, "lat", None), getattr(s, "lon", None)
            heard, own = self._last_heard(v, s, age)
            v.quiet = v.contact.expected(heard, self.lost_after_s,
                                         None if lat is None else (lat, lon), own)
            if v.quiet is None:
                return False
            a, b = v.quiet.window
            self.event(v.sysid, f"out of contact, as planned: a radio shadow of {b - a:.0f} s "
                                f"predicted; due back by {v.quiet.due_s:.0f} s, overdue "
                                f"after {v.quiet.overdue_s:.0f} s at today's pace",
                       out_of_contact=True, heard_s=round(v.quiet.heard_s, 3),
                       due_s=round(v.quiet.due_s, 3))
            v.quiet_flown, v.quiet_at = (self.now() - v.quiet.heard_s) * v.contact.pace, \
                self.now()
        now = self.now()
        v.quiet_flown += (now - v.quiet_at) * self._pace_unheard(v)
        v.quiet_at = now
        return v.quiet_flown <= v.quiet.allowed_s

    def _own_clock(self, v) -> float | None:
        """The vehicle's own clock (s since boot) now: its latest report's, carried on
        at its clock's rate to now (None unknown). A waypoint's reached report carries
        no time: timed by the last position's, up to a fifth of a wall second older
        (20 s of its clock at 100x), progress over a few waypoints read up to twice
        the plan's, and a vehicle due back from a shadow 1.8 s (180 s of flight)
        before it was."""
        return _own_at(self.links[v.sysid].state, time.monotonic())

    def _last_heard(self, v, state, age) -> tuple:
        """(monitor s, its own clock then) of the last time a vehicle was heard: its
        last message, ``age`` s ago, or its last report with a time since boot,
        whichever is later (a sped-up simulator's HEARTBEATs come on the wall clock,
        its reports on its own)."""
        heard = self.now() - age
        boot_at = getattr(state, "boot_at", None)
        if boot_at is None:
            return heard, None
        report = boot_at - self.t0
        if report >= heard:
            return report, state.boot_s
        return heard, _own_at(state, heard + self.t0)

    def _pace_unheard(self, v) -> float:
        """Fleet seconds per monitor second of a silent vehicle: its own pace on its
        plan, at the clock rate the vehicles still heard run at now (one machine's
        simulated fleet slows together under load; real autopilots all run at 1)."""
        rates = sorted(u.contact.clock_rate for s, u in self.vehicles.items()
                       if u is not v and u.quiet is None and not u.finished
                       and self.links[s].silent_s() <= self.lost_after_s)
        if not rates:
            return v.contact.pace
        return rates[len(rates) // 2] * v.contact.pace / v.contact.clock_rate

    def _back_in_contact(self, v) -> None:
        q, v.quiet = v.quiet, None
        now = self.now()
        v.silences.append({"from_s": round(q.heard_s, 3), "to_s": round(now, 3),
                           "due_s": round(q.due_s, 3), "window": list(q.window)})
        self.event(v.sysid, f"back in contact after {now - q.heard_s:.0f} s out of contact, "
                            f"{abs(now - q.due_s):.0f} s {'before' if now <= q.due_s else 'after'}"
                            f" it was due (overdue after {q.overdue_s:.0f} s)")

    def _lose_overdue(self, v) -> None:
        q = v.quiet
        v.silences.append({"from_s": round(q.heard_s, 3), "to_s": None,
                           "due_s": round(q.due_s, 3), "window": list(q.window)})
        self._lose(v, f"overdue: last heard at {q.heard_s:.0f} s entering a predicted radio "
                      f"shadow, due back by {q.due_s:.0f} s, not heard by "
                      f"{q.overdue_s:.0f} s", due_s=round(q.due_s, 3), silence=True)
        v._reported = True

    def _heard_back(self, v) -> bool:
        """Lost for a silence, and heard again since, position included: a report
        newer than that HEARTBEAT (the link's position from before the silence
        would place it where it was)."""
        s = self.links[v.sysid].state
        boot_at = getattr(s, "boot_at", None)
        return v.silent_loss and v.heard_after_loss_s is not None and \
            boot_at is not None and boot_at - self.t0 >= v.heard_after_loss_s and \
            self.links[v.sysid].silent_s() <= self.lost_after_s

    def _rejoin(self, v) -> None:
        """A vehicle lost for a silence and heard again: in the air (flying on by
        itself, as its mission tells it), or landed at a base of its flight. Taken
        back under the monitor (and so the guard) and handed to the flight to be
        re-planned with the others (`take_rejoined`); down anywhere else it stays
        lost."""
        s = self.links[v.sysid].state
        grounded = self._on_ground(s)
        if s.armed and grounded and self.on_pad(v.sysid):
            return      # touching down at its base or lifting off: judged once it is not
        flying = bool(s.armed) and not grounded
        landed = not s.armed and self.on_pad(v.sysid)
        v.silent_loss = False                # judged once: a loss again is a new one
        if not (flying or landed):
            self.event(v.sysid, "heard again after it was declared lost, down away from "
                                "its bases: not taken back; bring it home by hand")
            return
        back = round(self.now(), 3)
        v.rejoins.append({"lost_at_s": v.lost_at_s, "reason": v.lost_reason,
                          "heard_s": v.heard_after_loss_s, "back_s": back,
                          "as": FLYING if flying else LANDED})
        v.state = FLYING if flying else LANDED
        v.lost_at_s = v.lost_reason = v.heard_after_loss_s = v.quiet = None
        v.disarmed_at_s, v._reported = None, False
        if landed:
            v.landed_at_s = back
        self.catch_up(v.sysid)
        self._rejoined.append(v.sysid)
        self.event(v.sysid, "rejoined: heard again after it was declared lost, "
                            f"{'flying' if flying else 'landed at its base'}; back under the "
                            "monitor and the separation guard, re-planned with the others",
                   rejoined=True)

    def catch_up(self, sysid) -> None:
        """Every waypoint before the item a vehicle flies now (MISSION_CURRENT) was
        passed, heard or not: a vehicle back from a silence is credited with what it
        flew unheard (its MISSION_ITEM_REACHED reports were lost with the link)."""
        with self._lock:
            v, seq = self.vehicles[sysid], self.links[sysid].state.mission_seq
            if v.mission is not None and seq is not None and int(seq) > 0:
                self._passed(v, int(seq) - 1, timed=False)

    def take_rejoined(self) -> list:
        """Vehicles taken back after a loss since the last call: the flight re-plans
        the fleet with them."""
        with self._lock:
            taken, self._rejoined = self._rejoined, []
        return taken

    def _note_power(self, v, silent_s, swap) -> None:
        """Say when a vehicle down for its battery swap falls silent (powered down,
        not lost yet), and when it is heard again."""
        if swap and silent_s > self.lost_after_s and v.powered_down_at_s is None:
            v.powered_down_at_s = round(self.now() - silent_s, 3)
            self.event(v.sysid, f"silent at its base for {silent_s:.0f} s: taken for its "
                                f"battery swap powering it down; lost if not heard again "
                                f"within {self.swap_silence_s:g} s")
        elif silent_s <= self.lost_after_s and v.powered_down_at_s is not None:
            self.event(v.sysid, f"heard again after {self.now() - v.powered_down_at_s:.0f} s "
                                "powered down for its battery swap")
            v.powered_down_at_s = None

    def on_pad(self, sysid) -> bool:
        """Down at a base of its flight (within `LAUNCH_RADIUS_M`, at home height), whether
        or not its landing has been told yet (the disarm comes a few seconds after
        the touchdown)."""
        v, s = self.vehicles[sysid], self.links[sysid].state
        planned = self.planned_position(sysid)
        if planned is not None:     # out of contact as planned: where its plan has it
            return self._planned_on_pad(v, planned)
        agl, away = getattr(s, "relative_alt", None), self._from_base(v, s)
        return agl is not None and abs(agl) <= LANDED_AGL_M and away is not None \
            and away <= LAUNCH_RADIUS_M

    @staticmethod
    def _planned_on_pad(v, planned) -> bool:
        """Whether (lon, lat, alt AMSL) ``planned`` is down on a base of its route (a
        silent vehicle's plan landed it: in nobody's column until its next takeoff)."""
        lon, lat, alt = planned
        points = [getattr(v.route, "launch", None), getattr(v.route, "land", None)]
        return any(p is not None and abs(alt - p.alt_amsl) <= LANDED_AGL_M and
                   distance_m(p.lat, p.lon, lat, lon) <= LAUNCH_RADIUS_M for p in points)

    def silent(self, sysid) -> bool:
        """Nothing heard from ``sysid`` for ``lost_after_s`` of the time this ground
        station was running (`StallClock`: a starved ground station hears nothing
        from anyone, and would otherwise lose its whole fleet at once)."""
        age, stalled = self._silence(sysid)
        return age - stalled > self.lost_after_s

    def _silence(self, sysid) -> tuple:
        """(seconds since anything was heard from ``sysid``, of them the seconds this
        ground station stood still); the stall is only looked up past
        ``lost_after_s``."""
        age = self.links[sysid].silent_s()
        if age <= self.lost_after_s:
            return age, 0.0
        return age, self.stalls.stalled(time.monotonic() - age)

    def planned_at(self, sysid) -> float | None:
        """Where on its plan's clock a vehicle out of contact as planned is now (its
        planned trajectory stays its own until it is declared lost); None for one
        heard."""
        v = self.vehicles.get(sysid)
        if v is None or v.quiet is None or v.state == LOST:
            return None
        # where it was when last heard, and as far as the overdue count has it flown
        # since (`_as_planned`), on to now
        return v.quiet.fleet_s + v.quiet_flown + \
            (self.now() - v.quiet_at) * self._pace_unheard(v)

    def planned_position(self, sysid) -> tuple | None:
        """(lon, lat, alt AMSL) of a vehicle out of contact as planned, on its planned
        trajectory (`planned_at`); None for one heard."""
        at = self.planned_at(sysid)
        rows = self.vehicles[sysid].trajectory if at is not None else None
        if rows is None:
            return None
        return tuple(float(np.interp(at, rows[:, 0], rows[:, k])) for k in (1, 2, 3))

    def take_losses(self) -> list:
        """Vehicles found lost since the last call, by any `check_losses` (a loss
        found while waiting on other vehicles is not forgotten): the flight
        re-tasks once for them all."""
        with self._lock:
            taken, self._untaken = self._untaken, []
        return taken

    def losses_waiting(self) -> bool:
        """Losses found that `take_losses` has not handed out yet."""
        with self._lock:
            return bool(self._untaken)

    def _lose(self, v, reason: str, silence: bool = False, **extra) -> None:
        v.state = LOST
        v.lost_at_s = round(self.now(), 3)
        v.lost_reason = reason
        v.silent_loss = silence
        self.event(v.sysid, LOST, reason=reason, last_heartbeat_s=v.last_heartbeat_s, **extra)

    # -- views ------------------------------------------------------------------------
    def survivors(self) -> list:
        with self._lock:
            return [s for s, v in self.vehicles.items() if v.state != LOST]

    def all_finished(self) -> bool:
        with self._lock:
            return all(v.finished for v in self.vehicles.values())

    def status_rows(self) -> list:
        """One row per vehicle for the status table."""
        rows = []
        with self._lock:
            for sysid, v in sorted(self.vehicles.items()):
                s = self.links[sysid].state
                age = self.links[sysid].heartbeat_age()
                items = mission_items(v.mission)
                rows.append({
                    "sysid": sysid, "vehicle": v.vehicle_id, "mode": s.mode or "?",
                    "item": f"{_or_dash(shown_item(s, items))}/{items}",
                    "mission": v.generation,
                    "snapshots": f"{len(v.snapshots)} ({v.snapshots_done}/{v.snapshot_total})",
                    "alt": s.relative_alt, "heartbeat_s": age, "state": v.state,
                    "battery": s.battery_pct})
        return rows
