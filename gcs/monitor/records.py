"""The monitor's records: the flight states of a vehicle, the thresholds its
judgments use, and what it keeps of each vehicle (`VehicleProgress`, its
`Snapshot` list). Plain data: the judgments are the `Monitor`'s."""

from dataclasses import dataclass, field

import numpy as np

from gcs.contact import Contact, Expected
from missions.items import NAV_LAND

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
    last_heard_s: float | None = None  # of a silent loss: when anything was last heard
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
    # out of contact since (monitor s) until heard flying again: it may come down unheard
    unheard_from_s: float | None = None
    down_unheard: list = field(default_factory=list)  # [{"t_s", "from_s", "item", "final"}]
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
