"""Commands with acknowledgement: modes, arming, readiness, the start of a mission.

Every COMMAND_LONG / COMMAND_INT is re-sent until its COMMAND_ACK arrives (1.5 s,
up to 5 retries, `confirmation` counting up as the spec asks); a result other
than ACCEPTED raises CommandError naming the MAV_RESULT and, where the vehicle
explained itself in a STATUSTEXT ("PreArm: GPS 1: Bad fix"), its words.

Start sequences are each firmware's own, as steps in its `autopilots` profile
(``start_sequence``), executed here: ArduPilot takes off in GUIDED and then
switches to AUTO; PX4 starts the mission and then arms. In both the current
item is set first (after a new upload ArduPilot would otherwise resume at the
old index).
"""

import time

from autopilots import GENERIC_MODES
from gcs.mavlink import M, command_name, profile_of, result_name

TIMEOUT_S = 1.5
RETRIES = 5
CONFIRM_S = 3.0                 # how long a mode change may take to show in the HEARTBEAT
TEMPORARY_WAIT_S = 0.5          # pause before retrying a TEMPORARILY_REJECTED command
HEARTBEAT_LAG_S = 0.5           # a HEARTBEAT this long after a command reflects it


class CommandError(Exception):
    """A command was refused or never acknowledged; names vehicle, command, result."""

    def __init__(self, vehicle, problem: str, command: int | None = None,
                 result: int | None = None):
        self.sysid = getattr(vehicle, "sysid", vehicle)
        self.command = command
        self.result = result
        self.result_name = None if result is None else result_name(result)
        super().__init__(f"vehicle {self.sysid}: {problem}")


class StartCancelled(CommandError):
    """The ground station called a start sequence off (a re-plan takes the vehicle
    over): not a failure of the vehicle."""


# -- acknowledged commands -------------------------------------------------------------
def command_long(link, command: int, *params, timeout_s=TIMEOUT_S, retries=RETRIES):
    """Send COMMAND_LONG (params 1-7, missing ones 0) until acknowledged; returns the
    COMMAND_ACK. Raises CommandError on refusal or when no ACK comes."""
    p = [float(x) for x in params] + [0.0] * (7 - len(params))
    fields = {f"param{i + 1}": p[i] for i in range(7)}

    def send(attempt):
        link.send("COMMAND_LONG", command=command, confirmation=min(attempt, 255), **fields)

    return _acknowledged(link, command, send, timeout_s, retries)


def command_int(link, command: int, frame: int, params=(), x: int = 0, y: int = 0,
                z: float = 0.0, timeout_s=TIMEOUT_S, retries=RETRIES):
    """COMMAND_INT (x, y as degrees * 1e7 in global frames) until acknowledged."""
    p = [float(v) for v in params] + [0.0] * (4 - len(params))
    fields = {f"param{i + 1}": p[i] for i in range(4)}

    def send(_attempt):
        link.send("COMMAND_INT", command=command, frame=frame, x=int(x), y=int(y),
                  z=float(z), **fields)

    return _acknowledged(link, command, send, timeout_s, retries)


def _acknowledged(link, command, send, timeout_s, retries):
    is_ours = lambda ack: ack.command == command             # noqa: E731
    while link.recv("COMMAND_ACK", 0, is_ours) is not None:  # stale ACKs of this command
        pass
    texts_before = len(_texts(link))
    for attempt in range(retries + 1):
        send(attempt)
        sent = time.monotonic()
        deadline = sent + timeout_s
        while (left := deadline - time.monotonic()) > 0:
            ack = link.recv("COMMAND_ACK", left, is_ours)
            if ack is None:
                break
            if ack.result == M.MAV_RESULT_ACCEPTED:
                _round_trip(link, time.monotonic() - sent)
                return ack
            if ack.result == M.MAV_RESULT_IN_PROGRESS:
                deadline = time.monotonic() + timeout_s        # a long command: wait on
                continue
            if ack.result == M.MAV_RESULT_TEMPORARILY_REJECTED and attempt < retries:
                time.sleep(TEMPORARY_WAIT_S)
                break
            raise CommandError(link, f"{command_name(command)} refused: "
                                     f"{result_name(ack.result)}"
                                     f"{_explanation(link, texts_before)}",
                               command, ack.result)
    raise CommandError(link, f"no COMMAND_ACK for {command_name(command)} after "
                             f"{retries + 1} tries {timeout_s:g} s apart{_silence(link)}",
                       command)


def _round_trip(link, seconds) -> None:
    """Keep a command's way to the vehicle and its answer's way back (the separation
    guard's measure of how late it sees and acts: `gcs.guard`)."""
    kept = getattr(link, "round_trips", None)
    if kept is not None:
        kept.append(seconds)


def _texts(link) -> list:
    return list(getattr(link.state, "statustext", []))


def _explanation(link, since: int = 0) -> str:
    """What the vehicle said since the command went out (warnings and worse first)."""
    time.sleep(0.05)                           # the STATUSTEXT usually trails the ACK
    texts = _texts(link)[since:]
    if not texts:
        return ""
    worst = min(texts, key=lambda t: t[0])
    return f' (vehicle said: "{worst[1]}")'


def _silence(link) -> str:
    age = link.heartbeat_age()
    return f" (no HEARTBEAT for {age:.0f} s)" if age > 3 else ""


# -- the vehicle's firmware -------------------------------------------------------------
def autopilot(link):
    """The `autopilots` profile of a vehicle; CommandError for an autopilot with none."""
    found = getattr(link, "profile", None) or profile_of(getattr(link, "flavour", None))
    if found is None:
        raise CommandError(link, f"its autopilot ({getattr(link, 'flavour', '?')}) is neither "
                                 "ArduPilot nor PX4: no profile to command it with")
    return found


def _mode_profile(link):
    """The profile that names and packs modes: a generic autopilot is asked in
    ArduPilot's plain custom-mode numbers."""
    return getattr(link, "profile", None) or profile_of(getattr(link, "flavour", None)) \
        or profile_of(GENERIC_MODES)


# -- modes and arming ------------------------------------------------------------------
def set_mode(link, name: str, confirm=True, timeout_s=TIMEOUT_S, retries=RETRIES) -> None:
    """Switch to mode `name` (ArduPilot: "GUIDED", "AUTO", ...; PX4: "AUTO.MISSION",
    "AUTO.LOITER", "POSCTL", ...), then wait until the HEARTBEAT shows it.

    HEARTBEATs (1 Hz) get lost too: when none shows the mode within CONFIRM_S, the
    command goes out again (up to `retries` times; asking twice is harmless)."""
    modes = _mode_profile(link)
    try:
        custom, _, _ = modes.mode_number(name, link.mav_type)
        params = modes.set_mode_params(name, link.mav_type)
    except KeyError as exc:
        raise CommandError(link, exc.args[0]) from None
    for _ in range(retries + 1):
        _request_mode(link, custom, params, timeout_s, retries)
        if confirm and link.state.custom_mode != custom:
            # the HEARTBEAT that shows it comes once a second: ask for one now (a
            # second's wait is many seconds of a sped-up simulation, or a start late)
            link.send("COMMAND_LONG", command=M.MAV_CMD_REQUEST_MESSAGE, confirmation=0,
                      param1=float(M.MAVLINK_MSG_ID_HEARTBEAT), param2=0.0, param3=0.0,
                      param4=0.0, param5=0.0, param6=0.0, param7=0.0)
        if not confirm or _until(link, lambda s: s.custom_mode == custom, CONFIRM_S):
            return
    raise CommandError(link, f"mode is still {link.state.mode} after asking for "
                             f"{name.upper()} {retries + 1} times")


def _request_mode(link, custom, params, timeout_s, retries) -> None:
    """MAV_CMD_DO_SET_MODE with the firmware's params (ArduPilot: the custom mode;
    PX4: main and sub mode)."""
    flag = M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
    try:
        command_long(link, M.MAV_CMD_DO_SET_MODE, flag, *params,
                     timeout_s=timeout_s, retries=retries)
    except CommandError as exc:
        if exc.result != M.MAV_RESULT_UNSUPPORTED:
            raise
        link.send("SET_MODE", base_mode=flag, custom_mode=custom)   # older firmware


def arm(link, timeout_s=TIMEOUT_S, retries=RETRIES) -> None:
    """Arm; a refusal names the reason the vehicle gave (pre-arm failure etc.).

    The ACK is the confirmation: waiting for a HEARTBEAT (1 Hz) would eat into the
    few seconds before an idle armed copter disarms itself."""
    command_long(link, M.MAV_CMD_COMPONENT_ARM_DISARM, 1, timeout_s=timeout_s,
                 retries=retries)


def disarm(link, force=False) -> None:
    command_long(link, M.MAV_CMD_COMPONENT_ARM_DISARM, 0, 21196 if force else 0)


def set_current(link, seq: int, timeout_s=TIMEOUT_S, retries=RETRIES) -> None:
    """Make mission item `seq` the current one, confirmed by MISSION_CURRENT."""
    try:
        command_long(link, M.MAV_CMD_DO_SET_MISSION_CURRENT, seq, timeout_s=timeout_s,
                     retries=retries)
    except CommandError as exc:
        if exc.result != M.MAV_RESULT_UNSUPPORTED:
            raise
        _set_current_legacy(link, seq, timeout_s, retries)


def _set_current_legacy(link, seq, timeout_s, retries) -> None:
    """MISSION_SET_CURRENT (deprecated message): answered by MISSION_CURRENT."""
    link.flush("MISSION_CURRENT")
    for _ in range(retries + 1):
        link.send("MISSION_SET_CURRENT", seq=seq)
        if link.recv("MISSION_CURRENT", timeout_s, lambda m: m.seq == seq) is not None:
            return
    raise CommandError(link, f"the current mission item did not become {seq}")


def wait_ready(link, timeout_s: float = 60.0) -> None:
    """Wait until the vehicle reports it may arm (pre-arm checks, EKF, GPS) and has a
    position; CommandError saying what is missing after `timeout_s`."""
    _wait_for(link, lambda s: s.ready and s.lat is not None, timeout_s,
              lambda s: f"not ready to arm after {timeout_s:g} s: {_readiness(s)}")


def wait_position(link, timeout_s: float = 60.0) -> None:
    """Wait until the vehicle reports where it is; CommandError after ``timeout_s``."""
    _wait_for(link, lambda s: s.lat is not None, timeout_s,
              lambda s: f"no position reported after {timeout_s:g} s: {_readiness(s)}")


def _readiness(s) -> str:
    missing = []
    if s.gps_fix < M.GPS_FIX_TYPE_3D_FIX:
        missing.append(f"GPS fix type {s.gps_fix} (3D fix needed)")
    if not s.ready:
        missing.append("pre-arm checks failing (EKF / sensors)")
    if s.lat is None:
        missing.append("no position reported")
    texts = [t for sev, t in s.statustext if sev <= M.MAV_SEVERITY_WARNING]
    if texts:
        missing.append(f'last warning: "{texts[-1]}"')
    return "; ".join(missing) or "unknown reason"


def _wait_for(link, predicate, timeout_s, problem) -> None:
    if not _until(link, predicate, timeout_s):
        raise CommandError(link, problem(link.state))


def _until(link, predicate, timeout_s) -> bool:
    """Whether ``predicate(link.state)`` comes true within ``timeout_s``."""
    deadline = time.monotonic() + timeout_s
    while not predicate(link.state):
        if time.monotonic() >= deadline:
            return False
        time.sleep(0.05)
    return True


# -- the start sequence ----------------------------------------------------------------
def start_mission(link, takeoff_alt_amsl: float, ready_timeout_s: float = 60.0,
                  climb_timeout_s: float = 120.0, retries: int = RETRIES,
                  on_liftoff=None, cancel=None, column=None) -> None:
    """Take off and start the uploaded mission, as the vehicle's firmware expects
    (the steps of its profile's ``start_sequence``).

    takeoff_alt_amsl: where ArduPilot climbs in GUIDED before AUTO (m AMSL; the
    mission's own takeoff item then completes at once). PX4 flies its mission's
    takeoff item itself. Returns once the vehicle is airborne in its mission mode.
    retries: resends of each command (more on a lossy link); ``on_liftoff()``:
    called when the command that lifts it off is acknowledged (the moment a
    fleet's schedule is kept to); ``cancel`` (a `threading.Event`): once set, the
    sequence sends nothing more and raises `StartCancelled` (a re-plan is about
    to hold the vehicle where it is); ``column``: its base column, asked before
    each arming attempt (``claim()``: whether it may leave the ground now, and if so
    the column is kept for it) and waited for, given back on a refused arming
    (``release()``): arming is the last step before it lifts off (PX4 climbs as it
    arms in its mission mode, ArduPilot on the takeoff sent next)."""
    profile = autopilot(link)
    ready_by = time.monotonic() + ready_timeout_s
    wait_ready(link, ready_timeout_s)
    run = _StartRun(link, profile, takeoff_alt_amsl, climb_timeout_s, retries, ready_by,
                    on_liftoff or (lambda: None), cancel, column)
    for step in profile.start_sequence:
        run.check()
        getattr(run, step.action)(step.argument)


#: wall seconds between arming attempts refused while the vehicle gets ready
ARM_RETRY_S = 1.0
#: wall seconds between two looks at whether a vehicle's base column is clear
COLUMN_POLL_S = 0.1
#: takeoffs tried when the vehicle disarmed itself on the ground before climbing
TAKEOFF_ATTEMPTS = 3


class _StartRun:
    """The steps a start sequence is made of (`autopilots.base.Step`)."""

    def __init__(self, link, profile, takeoff_alt_amsl, climb_timeout_s, retries,
                 ready_by=None, on_liftoff=lambda: None, cancel=None, column=None):
        self.link, self.profile = link, profile
        self.on_liftoff = on_liftoff
        self.cancel = cancel
        self.column = column
        self.claimed = False                # the column is kept for this vehicle
        self.takeoff_alt_amsl = takeoff_alt_amsl
        self.climb_timeout_s, self.retries = climb_timeout_s, retries
        self.ready_by = ready_by            # until then a refused arming is tried again
        self.armed_at = None

    def check(self) -> None:
        if self.cancel is not None and self.cancel.is_set():
            raise StartCancelled(self.link, "start called off by the ground station")

    def _wait_airborne(self, climbed, doing) -> None:
        """`_wait_airborne`, given up (`StartCancelled`) once the start is called off."""
        _wait_airborne(self.link, self.armed_at,
                       lambda s: climbed(s) or (self.cancel is not None and self.cancel.is_set()),
                       self.climb_timeout_s, doing)
        self.check()

    def set_current(self, _=None) -> None:
        set_current(self.link, self.profile.first_item, retries=self.retries)

    def mode(self, name) -> None:
        set_mode(self.link, name, retries=self.retries)

    def arm(self, _=None) -> None:
        """Arm; refused (PX4 reports no pre-arm bit, so readiness is its arming
        result: "Arming denied" until its estimator is ready), try again until the
        ready timeout. Each attempt waits for its base column (the time waited is
        added to the ready timeout), which a refused attempt gives back."""
        while True:
            self._claim_column()
            try:
                arm(self.link, retries=self.retries)
                break
            except CommandError as exc:
                if self.column is not None:
                    self.column.release()
                    self.claimed = False
                self.check()
                if exc.result is None or self.ready_by is None or \
                        time.monotonic() + ARM_RETRY_S > self.ready_by:
                    raise
                time.sleep(ARM_RETRY_S)
        self.armed_at = time.monotonic()  # after the ACK (retries on a lossy link included)

    def _claim_column(self) -> None:
        """Wait for the base column and keep it; once armed it stays kept (an arming
        again after ArduPilot disarmed itself idle goes at once, as before)."""
        if self.column is None or self.claimed:
            return
        begun = time.monotonic()
        while not self.column.claim():
            self.check()
            time.sleep(COLUMN_POLL_S)
        self.claimed = True
        if self.ready_by is not None:
            self.ready_by += time.monotonic() - begun

    def mission_start(self, fallback_mode=None) -> None:
        try:
            command_long(self.link, M.MAV_CMD_MISSION_START, 0, 0, retries=self.retries)
        except CommandError as exc:
            if fallback_mode is None or exc.result is None:
                raise
            set_mode(self.link, fallback_mode, retries=self.retries)

    def takeoff(self, _=None) -> None:
        """MAV_CMD_NAV_TAKEOFF relative to home, then wait for the climb."""
        link = self.link
        home_alt = _home_alt(link)
        climb = self.takeoff_alt_amsl - home_alt
        if climb < 1.0:
            raise CommandError(link, f"takeoff altitude {self.takeoff_alt_amsl:.1f} m AMSL is "
                                     f"not above home ({home_alt:.1f} m AMSL)")
        target = climb - max(1.0, 0.05 * climb)
        for attempt in range(TAKEOFF_ATTEMPTS):
            try:
                self._send_takeoff(climb)
                self.on_liftoff()
                self._wait_airborne(lambda s: (s.relative_alt or 0.0) >= target,
                                    f"climbing to {climb:.1f} m above home")
                return
            except StartCancelled:
                raise
            except CommandError:
                # ArduPilot disarms itself idle on the ground (DISARM_DELAY, 10 s: at a
                # high --speedup a fraction of a wall second, which a busy ground
                # station may take between the arming and the takeoff): arm again
                if attempt + 1 == TAKEOFF_ATTEMPTS or not self._disarmed_on_the_ground():
                    raise
                self._not_brought_down_by_a_failsafe()
                self.arm()

    def _send_takeoff(self, climb) -> None:
        try:
            command_long(self.link, M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, climb,
                         retries=self.retries)
        except CommandError as exc:
            # on a lossy link the first ACK may be lost; the retry is then refused
            # because the takeoff is already under way
            if exc.result is None or not _climbing(self.link):
                raise

    def _not_brought_down_by_a_failsafe(self) -> None:
        """Down and disarmed in a failsafe's mode, the vehicle climbed and came back
        on its own: the flight has judged it down (a return, or a crash), so it is not
        sent up again here. (Real ArduPilot SITL: a GCS failsafe in the GUIDED takeoff
        climb, where FS_OPTIONS has no "continue", flew SmartRTL back to the pad; the
        re-arm then met "Arm: SMARTRTL mode not armable" until the ready timeout.)"""
        mode = self.link.state.mode
        if mode in self.profile.failsafe_modes:
            raise CommandError(self.link, f"a failsafe brought it back down in {mode} during "
                                          "its takeoff climb: not started again")

    def _disarmed_on_the_ground(self) -> bool:
        return _disarmed_since(self.link, self.armed_at) and \
            abs(self.link.state.relative_alt or 0.0) < 1.0

    def airborne(self, _=None) -> None:
        self.on_liftoff()                    # armed in its mission mode: it climbs
        self._wait_airborne(lambda s: (s.relative_alt or 0.0) > 1.0, "taking off")


def _climbing(link, wait_s: float = 3.0) -> bool:
    """Whether the vehicle is leaving the ground (within ``wait_s``)."""
    deadline = time.monotonic() + wait_s
    while time.monotonic() < deadline:
        if (link.state.relative_alt or 0.0) > 0.5:
            return True
        time.sleep(0.05)
    return False


def _disarmed_since(link, armed_at) -> bool:
    """Whether a HEARTBEAT sent after arming shows the vehicle disarmed."""
    s = link.state
    return not s.armed and (s.last_heartbeat or 0.0) > (armed_at or 0.0) + HEARTBEAT_LAG_S


def _wait_airborne(link, armed_at, climbed, timeout_s, doing) -> None:
    """Wait for `climbed(state)`; a HEARTBEAT sent after arming that shows the vehicle
    disarmed (it gave up, or disarmed itself idle on the ground) is an error."""
    _wait_for(link, lambda s: climbed(s) or _disarmed_since(link, armed_at), timeout_s,
              lambda s: f"still at {s.relative_alt or 0.0:.1f} m above home "
                        f"{timeout_s:g} s after {doing} started (mode {s.mode})")
    if _disarmed_since(link, armed_at):
        raise CommandError(link, f"disarmed while {doing}{_explanation(link)}")


def _home_alt(link) -> float:
    """Home's altitude (m AMSL) of a vehicle armed on the ground for its takeoff:
    where it stands, which ArduPilot made its home as it armed. The HOME_POSITION
    heard before may be an earlier home: a vehicle that landed at another base
    and armed again there climbed that base's height difference too high."""
    s = link.state
    if s.alt_amsl is not None:
        return s.alt_amsl
    if s.home is not None:
        return s.home[2]
    raise CommandError(link, "no home position or altitude reported yet")


__all__ = ["CommandError", "StartCancelled", "arm", "autopilot", "command_int",
           "command_long", "disarm", "set_current", "set_mode", "start_mission",
           "wait_position", "wait_ready"]
