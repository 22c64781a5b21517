"""The vehicle-side mirror of the `autopilots` profiles: how a simulated copter of
each firmware behaves where a ground station can tell.

Mode numbers and their packing, home as mission item 0, which modes hold, fly
the mission, land, return or take positions, the camera command and the item
capacity come from the firmware's profile (the same one the ground station
uses); a `Flavour` adds what only the vehicle side needs: what each mode makes
the vehicle do, which modes may arm, protocol quirks, what it says, and the
endpoints real SITL uses. The vehicle (`gcs.sim.vehicle`) reads these flags and
never tests a firmware's name.
"""

from dataclasses import dataclass, field
from typing import Callable

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from autopilots import ARDUPILOT as ARDUPILOT_NAME
from autopilots import PX4 as PX4_NAME
from autopilots import Autopilot, profile
from gcs.sim.battery import CAPACITY_MAH, ardupilot_levels, px4_levels
from gcs.sim.link_loss import LinkLoss, ardupilot_link_loss, px4_link_loss

# What a mode makes the vehicle do (see vehicle.py).
MANUAL, GUIDED, AUTO, RTL, LAND, TAKEOFF = "manual", "guided", "auto", "rtl", "land", "takeoff"
SMARTRTL = "smartrtl"              # its own saved path back (`gcs.sim.smartrtl`)


@dataclass(frozen=True)
class Texts:
    """STATUSTEXTs of a flavour: arming refusals, readiness, a mission too long."""
    refused: str                   # arming refused on request (--refuse-arm)
    no_gps: str
    no_ekf: str
    bad_mode: str
    ready: str
    no_space: str | None = None    # with a NO_SPACE refusal, "{n}" the capacity


@dataclass(frozen=True)
class Boot:
    """When a freshly started autopilot gets there, in simulated seconds (divided by
    the speedup on the wall clock), as its SITL does: GPS fix, EKF origin (a
    position in GLOBAL_POSITION_INT), ready to arm."""
    gps_s: float
    origin_s: float
    ready_s: float


@dataclass(frozen=True)
class Flavour:
    profile: Autopilot             # the firmware's profile, shared with the ground station
    behaviour: dict                # mode name -> MANUAL | GUIDED | AUTO | RTL | LAND | TAKEOFF
    initial_mode: str
    armable: frozenset             # modes that allow arming (AUTO on ArduPilot: see AUTO_OPTIONS)
    legacy_request: bool           # asks for items with MISSION_REQUEST, not _INT (ArduPilot)
    nacks_out_of_order: bool       # an upload's item out of order: MISSION_ACK
                                   # INVALID_SEQUENCE, the transfer still open (ArduPilot's
                                   # MissionItemProtocol); asked again at once either way
    reached_after_do_items: bool   # MISSION_ITEM_REACHED once the DO commands after a
                                   # navigation item are done, with the last one's seq (PX4)
    resume_old_index: bool         # a new upload keeps the current index (ArduPilot)
    holds_in_hold_mode: bool       # at a mission's end switches to its hold mode (PX4:
                                   # AUTO.LOITER); ArduCopter stays in AUTO, loitering
                                   # (both seen on real SITL)
    arm_in_auto_starts: bool       # arming in the mission mode takes off at once (PX4)
    start_needs_armed: bool        # MISSION_START is refused while disarmed (ArduPilot)
    takeoff_mode: str | None       # NAV_TAKEOFF switches to this mode, altitude AMSL (PX4);
                                   # None: climbs in GUIDED, altitude above home (ArduPilot)
    reposition_int_only: bool      # DO_REPOSITION only as COMMAND_INT (ArduPilot)
    reposition_needs_flag: bool    # outside GUIDED only with the CHANGE_MODE flag (ArduPilot)
    says_reached: bool             # a "Reached command #N" STATUSTEXT (ArduPilot)
    camera_feedback: bool          # CAMERA_FEEDBACK (ArduPilot), else CAMERA_IMAGE_CAPTURED
    ekf_status: bool               # streams EKF_STATUS_REPORT (ArduPilot)
    version: tuple                 # (major, minor) in AUTOPILOT_VERSION
    texts: Texts
    deny_result: int               # COMMAND_ACK result of a refused arm
    transport: str                 # "tcp": TCP server per vehicle (ArduPilot SITL);
                                   # "udp": sends to the ground station's port (PX4 SITL)
    base_port: int                 # first SITL port
    port_step: int                 # between instances
    banner: bytes = b""            # plain text greeting the first TCP client
    boot: Boot = Boot(1.0, 1.0, 2.0)
    boot_on_connect: bool = False  # starts only when the first TCP client connects
                                   # (ArduPilot SITL waits for it on SERIAL0)
    streams_on_request: bool = False   # only HEARTBEAT until a ground station asks
                                       # (REQUEST_DATA_STREAM / SET_MESSAGE_INTERVAL)
    zero_position: bool = False    # GLOBAL_POSITION_INT reads 0, 0 until the EKF origin;
                                   # else none is sent until then
    params: dict = field(default_factory=dict)
    modes: dict = field(default_factory=dict)    # mode name -> custom_mode (from the profile)
    #: the INT32 parameters: sent bytewise where the profile says so, set only as INT32
    int_params: frozenset = frozenset()
    #: params -> the battery failsafes they set (`gcs.sim.battery.Failsafe`), highest first
    battery_levels: Callable = lambda params: []
    #: params -> its ground-station link-loss failsafe (`gcs.sim.link_loss.LinkLoss`)
    link_loss: Callable = lambda params: LinkLoss(5.0, None, None)

    def __post_init__(self):
        if not self.modes:
            object.__setattr__(self, "modes", {name: self.profile.mode_number(name)[0]
                                               for name in self.behaviour})

    # -- from the profile -------------------------------------------------------------
    @property
    def name(self) -> str:
        return self.profile.name

    @property
    def autopilot(self) -> int:
        return self.profile.mav_autopilot

    @property
    def home_item(self) -> bool:
        return self.profile.home_item

    @property
    def first_item(self) -> int:
        return self.profile.first_item

    @property
    def hold_mode(self) -> str:
        """Where a finished mission or a takeoff leaves the vehicle."""
        return self.profile.mission_end_mode

    @property
    def mission_mode(self) -> str:
        return self.profile.mission_mode

    @property
    def land_mode(self) -> str:
        return self.profile.land_mode

    @property
    def rtl_mode(self) -> str:
        return self.profile.rtl_mode

    @property
    def guided_mode(self) -> str:
        return self.profile.guided_mode

    @property
    def capacity(self) -> int | None:
        return self.profile.mission_capacity

    # -- modes ------------------------------------------------------------------------
    def custom_mode(self, mode: str) -> int:
        return self.modes[mode]

    def mode_named(self, custom_mode: int) -> str | None:
        """The simulated mode behind a custom_mode; None for one it does not fly."""
        name = self.profile.mode_of(custom_mode)
        return name if name in self.modes else None

    def mode_from_command(self, param2: float, param3: float) -> str | None:
        """MAV_CMD_DO_SET_MODE as the firmware packs it (PX4: sub mode in param3)."""
        return self.mode_named(self.profile.mode_from_set_mode(param2, param3))


ARDUPILOT = Flavour(
    profile=profile(ARDUPILOT_NAME),
    behaviour={"STABILIZE": MANUAL, "AUTO": AUTO, "GUIDED": GUIDED, "LOITER": GUIDED,
               "RTL": RTL, "LAND": LAND, "SMART_RTL": SMARTRTL},
    initial_mode="STABILIZE",
    armable=frozenset({"STABILIZE", "GUIDED", "LOITER"}),
    legacy_request=True,
    nacks_out_of_order=True,
    reached_after_do_items=False,
    resume_old_index=True,
    holds_in_hold_mode=False,
    arm_in_auto_starts=False,
    start_needs_armed=True,
    takeoff_mode=None,
    reposition_int_only=True,
    reposition_needs_flag=True,
    says_reached=True,
    camera_feedback=True,
    ekf_status=True,
    version=(4, 7),
    texts=Texts(refused="PreArm: Simulated arming failure", no_gps="PreArm: GPS 1: Bad fix",
                no_ekf="PreArm: EKF3 still initialising", bad_mode="Arm: Mode not armable",
                ready="EKF3 IMU0 is using GPS", no_space="Only {n} items are supported"),
    deny_result=mavlink.MAV_RESULT_FAILED,
    transport="tcp",
    base_port=5760,
    port_step=10,
    banner=(b"Init ArduCopter V4.7.0-dev (simulated)\r\n"
            b"Free RAM: 65535\r\nFrame: QUAD/PLUS\r\n"),
    # ArduCopter 4.7 SITL at --speedup 1: GPS ~10 s, EKF origin ~20 s, arming in
    # GUIDED accepted ~45 s after the first client connects
    boot=Boot(gps_s=10.0, origin_s=20.0, ready_s=45.0),
    boot_on_connect=True,
    streams_on_request=True,
    zero_position=True,
    params={"AUTO_OPTIONS": 0.0, "WPNAV_RADIUS": 200.0, "RTL_ALT": 1500.0,
            # the failsafes' actions set, their capacity levels off (0) as the
            # firmware's defaults are: a vehicle sets BATT_LOW_MAH / BATT_CRT_MAH
            "DISARM_DELAY": 10.0, "BATT_CAPACITY": float(CAPACITY_MAH),
            "BATT_LOW_MAH": 0.0, "BATT_FS_LOW_ACT": 2.0,
            "BATT_CRT_MAH": 0.0, "BATT_FS_CRT_ACT": 1.0,
            # the other failsafes at ArduCopter 4.7's defaults (autopilots.ardupilot
            # FAILSAFES): link loss off, RC loss RTL, no option, fence off
            "FS_GCS_ENABLE": 0.0, "FS_THR_ENABLE": 1.0, "FS_OPTIONS": 16.0,
            "FENCE_ENABLE": 0.0, "FENCE_ACTION": 1.0, "FS_EKF_ACTION": 1.0,
            "SRTL_POINTS": 300.0, "SRTL_ACCURACY": 2.0},
    battery_levels=ardupilot_levels,
    link_loss=ardupilot_link_loss,
)

PX4 = Flavour(
    profile=profile(PX4_NAME),
    behaviour={"MANUAL": MANUAL, "POSCTL": MANUAL, "AUTO.TAKEOFF": TAKEOFF,
               "AUTO.LOITER": GUIDED, "AUTO.MISSION": AUTO, "AUTO.RTL": RTL,
               "AUTO.LAND": LAND},
    initial_mode="AUTO.LOITER",
    armable=frozenset({"MANUAL", "POSCTL", "AUTO.TAKEOFF", "AUTO.LOITER", "AUTO.MISSION"}),
    legacy_request=False,
    nacks_out_of_order=False,
    reached_after_do_items=True,
    resume_old_index=False,
    holds_in_hold_mode=True,
    arm_in_auto_starts=True,
    start_needs_armed=False,
    takeoff_mode="AUTO.TAKEOFF",
    reposition_int_only=False,
    reposition_needs_flag=False,
    says_reached=False,
    camera_feedback=False,
    ekf_status=False,
    version=(1, 15),
    texts=Texts(refused="Preflight Fail: simulated arming failure",
                no_gps="Preflight Fail: GPS fix too low",
                no_ekf="Preflight Fail: ekf2 missing data",
                bad_mode="Arming denied: not possible in this flight mode",
                ready="Ready for takeoff!"),
    deny_result=mavlink.MAV_RESULT_DENIED,
    transport="udp",
    base_port=18570,
    port_step=1,
    # PX4 v1.17 SIH: HEARTBEAT ~1-2 s after start, arming accepted ~3-7 s
    boot=Boot(gps_s=1.5, origin_s=2.0, ready_s=5.0),
    params={"NAV_ACC_RAD": 2.0, "RTL_RETURN_ALT": 15.0, "COM_DISARM_PRFLT": 10.0,
            "COM_LOW_BAT_ACT": 3.0, "BAT_LOW_THR": 0.15, "BAT_CRIT_THR": 0.07,
            "BAT_EMERGEN_THR": 0.05,
            # the other failsafes at PX4 1.17's defaults (autopilots.px4 FAILSAFES)
            "RTL_TYPE": 0.0, "NAV_DLL_ACT": 0.0, "COM_DLL_EXCEPT": 0.0, "NAV_RCL_ACT": 2.0,
            "COM_RCL_EXCEPT": 0.0, "GF_ACTION": 2.0, "COM_POS_LOW_ACT": 3.0,
            "COM_POS_LOW_EPH": -1.0},
    int_params=frozenset({"COM_LOW_BAT_ACT", "RTL_TYPE", "NAV_DLL_ACT",
                          "COM_DLL_EXCEPT", "NAV_RCL_ACT", "COM_RCL_EXCEPT", "GF_ACTION",
                          "COM_POS_LOW_ACT"}),
    battery_levels=px4_levels,
    link_loss=px4_link_loss,
)

FLAVOURS = {f.name: f for f in (ARDUPILOT, PX4)}


def flavour(firmware: str) -> Flavour:
    """The simulated flavour of ``firmware``; ValueError naming the choices."""
    if firmware not in FLAVOURS:
        raise ValueError(f"unknown firmware {firmware!r}; known: {', '.join(FLAVOURS)}")
    return FLAVOURS[firmware]
