# Over 600 lines, knowingly: the simulated vehicle's state machine answers every command
# against one state (mode, mission, position, battery) on its own thread, as an autopilot does.
"""One simulated multicopter: its state machine and command handling.

The vehicle runs in its own thread (`run`). Two clocks: telemetry rates, the
GPS/EKF warm-up, the no-upload second after boot and link cuts run on the wall
clock, so a ground station's timeouts behave as in the field; flight physics,
mission hold times and the track run on mission time, which advances `speedup`
times faster (in a fleet, no further than its slowest vehicle: `gcs.sim.lockstep`).
"""

import math
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from autopilots import ARDUPILOT
from common.geo import LocalFrame
from gcs.busy import busy_now
from gcs.sim import flavours as fl
from gcs.sim import params as sim_params
from gcs.sim import smartrtl, telemetry
from gcs.sim.battery import Battery
from gcs.sim.faults import FaultPlan, LinkFaults
from gcs.sim.mission_server import GLOBAL_FRAMES, MissionServer
from gcs.sim.physics import Limits, PointMass
from gcs.sim.track import TrackRecorder
from gcs.sim.transport import PtyLink, TcpServerLink, UdpLink
from planner.rates import waypoint_stop_s

M = mavlink
TICK_S = 0.02            # wall period of the vehicle loop
PHYSICS_STEP_S = 0.05    # largest mission-time step of the point mass
RADIO_PERIOD_S = 0.5     # mission s between two looks of the radio's line of sight
STEP_BUDGET_S = TICK_S   # wall time one tick may spend stepping mission time
#: ticks of mission time (at the speed-up) a vehicle of a fleet may step ahead of its
#: slowest vehicle (`gcs.sim.lockstep`), and the least such lead (mission s)
LEAD_TICKS, LEAD_MIN_S = 3, 0.5
#: wall seconds after a landing before a swap may power the autopilot down: a crew
#: needs that long (at a speed-up, `swap_s` of mission time can be less than the
#: second between two HEARTBEATs: the ground station would not know it landed)
CREW_WALL_S = 3.0
FLUSH_S = 2.0            # wall period of track file writes
FORCE_DISARM = 21196
TAKEOFF_TOLERANCE_M = 0.5
#: VehicleConfig.mission_capacity: what the firmware's profile says
FIRMWARE_CAPACITY = "firmware"

_WAYPOINT_LIKE = (M.MAV_CMD_NAV_WAYPOINT, M.MAV_CMD_NAV_LOITER_UNLIM,
                  M.MAV_CMD_NAV_LOITER_TURNS, M.MAV_CMD_NAV_LOITER_TIME,
                  M.MAV_CMD_NAV_SPLINE_WAYPOINT, M.MAV_CMD_NAV_LOITER_TO_ALT)


@dataclass
class VehicleConfig:
    sysid: int
    port: int                                  # TCP listen (ArduPilot) or UDP bind (PX4)
    firmware: str = ARDUPILOT                  # an autopilots profile name
    home: tuple = (-35.363261, 149.165230, 584.0)   # lat, lon deg; ground alt m AMSL
    gcs_address: tuple = ("127.0.0.1", 14550)  # PX4: where telemetry goes
    bind_host: str = "127.0.0.1"
    speedup: float = 1.0
    limits: Limits = field(default_factory=Limits)
    warmup_s: float | None = None              # wall s until GPS/EKF are ready to arm;
                                               # None: the firmware's boot times / speedup
    no_space_s: float = 1.0                    # wall s after boot refusing uploads (ArduPilot)
    auto_disarm_s: float = 10.0                # mission s armed on the ground idle; 0 = never
    camera: bool = True                        # a camera is configured: feedback messages
    auto_options: int = 0                      # ArduPilot AUTO_OPTIONS (bit 0: arm in AUTO)
    wp_radius_m: float = 2.0
    rtl_alt_m: float = 15.0                    # above home
    drop_pct: float = 0.0
    faults: FaultPlan = field(default_factory=FaultPlan)
    track_path: Path | None = None
    seed: int = 0
    signing_key: bytes | None = None           # sign what we send, require signed input
    terrain: Callable | None = None            # (lat, lon) -> ground m AMSL; None: flat
    radio: Callable | None = None              # (lat, lon, alt AMSL) -> the ground station
    #                                            hears it (planner.link.contact_at); None: always
    transport: str | None = None               # "pty": a serial line; None: the flavour's
    mission_capacity: int | None | str = FIRMWARE_CAPACITY   # items held; None: no limit
    battery_min: float = 60.0                  # flight time from a full battery to empty
    swap_s: float = 60.0                       # mission s disarmed on the ground until the
                                               # crew has put in a full battery
    swap_reboot_s: float = 0.0                 # wall s powered down by each swap (a flight
                                               # controller fed by its pack); 0: hot swap


class _LinkWriter:
    """File-like sink for pymavlink: every packet passes the fault filter first."""

    def __init__(self, vehicle):
        self._v = vehicle

    def write(self, buf: bytes) -> None:
        v = self._v
        if v.link is not None and not v.dead and v.off_until is None and \
                v.link_faults.passes(time.monotonic()):
            v.link.send(bytes(buf))


class SimVehicle:
    def __init__(self, cfg: VehicleConfig, lockstep=None):
        """``lockstep``: its fleet's `gcs.sim.lockstep.Lockstep` (None: its own clock)."""
        self.cfg = cfg
        self.lockstep = lockstep
        self._lead_s = max(LEAD_MIN_S, LEAD_TICKS * TICK_S * cfg.speedup)
        self.flavour = fl.flavour(cfg.firmware)
        self.sysid = cfg.sysid
        self.mav = M.MAVLink(_LinkWriter(self), srcSystem=cfg.sysid,
                             srcComponent=M.MAV_COMP_ID_AUTOPILOT1)
        self.mav.robust_parsing = True
        if cfg.signing_key is not None:
            self.mav.signing.secret_key = cfg.signing_key
            self.mav.signing.link_id = 0
            self.mav.signing.sign_outgoing = True
        lat, lon, alt = cfg.home
        self.frame = LocalFrame(lat, lon)
        self._home_ground = float(alt)
        self._geo_memo = self._ground_memo = (None, None)    # ((x, y), its value)
        self.home = (0.0, 0.0, self._home_ground)    # local x, y, alt
        self.limits = cfg.limits.of_firmware(self.flavour.profile.rates)
        self.body = PointMass((0.0, 0.0, self._home_ground), self.limits)
        self.link_faults = LinkFaults(cfg.drop_pct, seed=cfg.seed * 7919 + cfg.sysid)
        self.plan = cfg.faults
        self.params = dict(self.flavour.params, SYSID_THISMAV=float(cfg.sysid))
        for name, rate, unit in self.flavour.profile.rate_limits:   # what it flies by
            self.params[name] = getattr(self.limits, rate) / unit
        if "AUTO_OPTIONS" in self.params:
            self.params["AUTO_OPTIONS"] = float(cfg.auto_options)
        self.track = TrackRecorder(cfg.track_path, cfg.sysid, cfg.firmware, cfg.home)
        self.smart_path = None        # ArduPilot's SmartRTL path, from arming
        self.link = None
        self.mission = None
        self.mode = self.flavour.initial_mode
        self.armed = False
        self.landed = True
        self.current = self.flavour.first_item
        self.auto_started = False      # ArduPilot: MISSION_START received (auto_armed)
        self.task = None               # what the vehicle is doing, see _update_task
        self.t = 0.0                   # mission time since boot, s
        self.dead = False
        self.removed = threading.Event()   # set once it is shot down (`killed_at`: when)
        self.boot_wall = None
        self.off_until = None          # powered down until then (monotonic), by a swap
        self._ready_announced = False
        self._idle_since = None
        self._cuts_done = set()
        self._radio_next_t = 0.0       # mission time of the radio's next look
        self._heard_gcs = False        # a ground station's HEARTBEAT came (its link is up)
        self._cut_since_t = None       # mission time its link was cut at, while it is
        self._link_failsafe_fired = False   # in this cut
        self._periods = {}
        self._streams_requested = False
        self._warm = (math.inf, math.inf, math.inf)   # gps, origin, ready: wall s after boot
        self._default_streams()
        self._due = {}
        self._clients_seen = 0
        self._images = 0
        self.battery = Battery(60.0 * cfg.battery_min, drain=self.plan.drain)
        self.ground_s = 0.0               # disarmed on the ground since (mission s)
        self._down_wall = None            # and since then (monotonic)
        self.heading = 0.0
        self._last_dest = None         # destination of the last nav item reached
        # PX4: the item the mission was left at (AUTO left in the air), and whether a
        # camera item of this mission has run: flown on, it rewinds (`_rewound`)
        self._left_at = None
        self._resuming = False         # a mission started in the air, its first item next
        self._camera_ran = False
        self._stop = threading.Event()
        self._kill = threading.Event()
        self._next_flush = 0.0
        self._takeoff_alt = self.ground + 2.5     # PX4 AUTO.TAKEOFF target, m AMSL

    @property
    def ground(self) -> float:
        """Ground altitude (m AMSL) under the vehicle: the configured terrain, or
        flat at the home altitude as in ArduPilot and PX4 SITL."""
        if self.cfg.terrain is None:
            return self._home_ground
        at = (self.body.pos[0], self.body.pos[1])
        if self._ground_memo[0] != at:     # asked twice a physics step, and while landed
            ground = self.cfg.terrain(*self._geo())
            self._ground_memo = (at, float(ground) if math.isfinite(ground)
                                 else self._home_ground)
        return self._ground_memo[1]

    def _geo(self) -> tuple:
        """(lat, lon) of the true position, converted once per position (a pyproj call:
        the ground, the track and the telemetry of a step all ask)."""
        at = (self.body.pos[0], self.body.pos[1])
        if self._geo_memo[0] != at:
            self._geo_memo = (at, self.frame.to_geo(*at))
        return self._geo_memo[1]

    # -- life cycle -------------------------------------------------------------------
    def open(self) -> None:
        """Bind the sockets (raises OSError if the port is taken) and boot."""
        cfg = self.cfg
        if cfg.transport == "pty":
            self.link = PtyLink()
        elif self.flavour.transport == "tcp":
            self.link = TcpServerLink(cfg.port, cfg.bind_host, self.flavour.banner)
        else:
            self.link = UdpLink(cfg.port, tuple(cfg.gcs_address), cfg.bind_host)
        capacity = self.flavour.capacity if cfg.mission_capacity == FIRMWARE_CAPACITY \
            else cfg.mission_capacity
        self.mission = MissionServer(self.flavour, self.mav, self._send, self._say,
                                     self.home_geo, lambda: self.current,
                                     self._mission_changed, time.monotonic(), cfg.no_space_s,
                                     capacity=capacity)
        if not (self.flavour.boot_on_connect and isinstance(self.link, TcpServerLink)):
            self._boot(time.monotonic())

    def _boot(self, now: float) -> None:
        """Start the autopilot (ArduPilot SITL: when the first client connects)."""
        self.boot_wall = now
        if self.lockstep is not None:
            self.lockstep.join(self)
        self.mission.booted(now)
        warm = self.cfg.warmup_s
        boot = self.flavour.boot
        if warm is None:                  # the firmware's own times, sped up
            scale = 1.0 / max(self.cfg.speedup, 1e-9)
            self._warm = (boot.gps_s * scale, boot.origin_s * scale, boot.ready_s * scale)
        else:                             # ready after warmup_s, in the same proportions
            self._warm = (warm / 2, warm * min(1.0, boot.origin_s / boot.ready_s), warm)
        self.track.event(self.t, "boot")
        self._sample(force=True)

    def run(self) -> None:
        """The vehicle loop; returns on stop() or kill."""
        last = next_tick = time.monotonic()
        try:
            while not self._stop.is_set() and not self.dead:
                if self._kill.is_set():
                    self._die("killed on request")
                    break
                chunks = self.link.poll(max(0.0, next_tick - time.monotonic()))
                now = time.monotonic()
                if self.off_until is not None:       # powered down: deaf, mute
                    chunks = []
                    if now >= self.off_until:
                        self._power_on(now)
                if self.boot_wall is None:           # waiting for the first client
                    if self.link.accepted:
                        self._boot(now)
                    last = next_tick = now
                    continue
                for chunk in chunks:
                    self._receive(chunk, now)
                if now >= next_tick:
                    self._advance(now - last, now)
                    last = now
                    next_tick = max(next_tick + TICK_S, now)
        finally:
            if self.lockstep is not None:
                self.lockstep.leave(self)
            if not self.dead:
                self.link.close()
                self.track.flush(complete=True)

    def stop(self) -> None:
        self._stop.set()

    def request_kill(self) -> None:
        self._kill.set()

    def _die(self, reason: str) -> None:
        """Shot down: no more output, sockets closed at once (as a dead SITL's)."""
        self.track.killed_at = round(self.t, 3)
        self.track.event(self.t, f"killed: {reason}")
        self._sample(force=True)
        self.dead = True
        if self.lockstep is not None:
            self.lockstep.leave(self)
        self.link.close()
        self.track.flush(complete=True)
        self.removed.set()

    # -- state seen from outside ------------------------------------------------------
    def position(self) -> tuple:
        """(lat, lon, alt AMSL) of the true position."""
        return (*self._geo(), self.body.pos[2])

    def _booted_for(self) -> float:
        return -1.0 if self.boot_wall is None else time.monotonic() - self.boot_wall

    @property
    def ready(self) -> bool:
        """Pre-arm checks pass (EKF and GPS good)."""
        return self._booted_for() >= self._warm[2]

    @property
    def has_origin(self) -> bool:
        """The EKF has an origin: GLOBAL_POSITION_INT holds a position."""
        return self._booted_for() >= self._warm[1]

    @property
    def gps_fix(self) -> bool:
        return self._booted_for() >= self._warm[0]

    # -- time -------------------------------------------------------------------------
    def _advance(self, wall_dt: float, now: float) -> None:
        # a machine too slow for `speedup` gets slower mission time, not a vehicle
        # that falls ever further behind and stops streaming (no HEARTBEAT: 'lost');
        # while the ground station in this process is busy (a re-plan, an upload)
        # mission time runs at real time, as a real flight lives that spell
        speed = self.cfg.speedup
        if busy_now() and speed > 1.0:
            speed = 1.0
            self.track.real_time_s += wall_dt
        remaining = wall_dt * speed
        if self.lockstep is not None:     # the fleet's one clock: not past its slowest
            remaining = min(remaining, self.lockstep.allowed(self, self._lead_s))
        give_up = time.monotonic() + STEP_BUDGET_S
        t0 = self.t
        while remaining > 1e-9 and not self.dead and time.monotonic() < give_up:
            dt = min(PHYSICS_STEP_S, remaining)
            remaining -= dt
            self.t += dt
            self._physics(dt)
            self._save_path()
            self._update_task()
            self._scheduled_faults(now)
            self._radio_shadow()
            self._link_failsafe(now)
            self._sample()
        if self.lockstep is not None:
            self.lockstep.stepped(self, self.t - t0)
        if self.dead:
            return
        self.mission.tick(now)
        self._announce_ready()
        self._stream(now)
        if now >= self._next_flush:
            self._next_flush = now + FLUSH_S
            self.track.flush()

    def _physics(self, dt: float) -> None:
        if self.landed:
            self.body.vel = [0.0, 0.0, 0.0]
            self._swap_battery(dt)
            return
        kind = self.task["kind"] if self.task else None
        lim, agl = self.limits, self.body.pos[2] - self.ground
        climb, descent = lim.climb_mps, lim.descent_mps
        if kind == "fall":
            descent = 10.0
        elif kind in ("land", "rtl") and agl < lim.land_band_m:
            descent = min(descent, lim.land_mps)
        elif kind == "takeoff" and agl < lim.takeoff_band_m:
            climb = min(climb, lim.takeoff_mps)
        self.body.climb_mps, self.body.descent_mps = climb, descent
        self.body.step(dt)
        self.battery.draw(dt, self.body.vel[2])
        self._battery_failsafes()
        self.ground_s, self._down_wall = 0.0, None
        if math.hypot(self.body.vel[0], self.body.vel[1]) > 0.5:
            self.heading = math.degrees(math.atan2(self.body.vel[0], self.body.vel[1])) % 360
        if self.body.pos[2] <= self.ground:
            self._touch_down()

    def _swap_battery(self, dt: float) -> None:
        """Disarmed on the ground `swap_s` after a flight: a full battery is in, the
        autopilot powered down meanwhile for `swap_reboot_s` wall seconds if set (no
        sooner than `CREW_WALL_S` after the landing)."""
        if self.armed:
            self.ground_s, self._down_wall = 0.0, None
            return
        self.ground_s += dt
        if self._down_wall is None:
            self._down_wall = time.monotonic()
        if self.battery.used_s > 0 and self.ground_s >= self.cfg.swap_s:
            if self.cfg.swap_reboot_s > 0 and time.monotonic() - self._down_wall < CREW_WALL_S:
                return
            self.battery.swap()
            self.track.event(self.t, "battery swapped")
            if self.cfg.swap_reboot_s > 0:
                self._power_off()

    def _power_off(self) -> None:
        """Silent, deaf, its TCP port closed (as SITL rebooting) until `_power_on`."""
        self.off_until = time.monotonic() + self.cfg.swap_reboot_s
        self.link.power_off()
        self.track.event(self.t, "powered down")

    def _power_on(self, now: float) -> None:
        """Booted again: modes, streams and the GPS and EKF warm-up as after power-up;
        the mission and parameters kept (as in the autopilot's storage)."""
        if not self.link.power_on():
            return                        # the port is not free yet: next tick
        self.off_until = None
        self.mode, self.current = self.flavour.initial_mode, self.flavour.first_item
        self.auto_started, self.task = False, None
        self._streams_requested, self._ready_announced = False, False
        self._default_streams()
        self._boot(now)

    def _battery_failsafes(self) -> None:
        """What the firmware does as the charge falls through its failsafe levels (each
        once per pack). An empty pack is recorded (the track's ``used`` passes 1), not
        flown into the ground: at a speed-up each wall second the ground station
        thinks (a re-plan) is that many seconds of hovering, which in the field cost
        a second."""
        if not self.armed:                  # falling: motors off already
            return
        if self.battery.remaining_pct <= 0.0 and "empty" not in self.battery.fired:
            self.battery.fired.add("empty")
            self.track.event(self.t, "battery empty")
        for level in self.battery.due(self.flavour.battery_levels(self.params)):
            text = f"Battery 1 is {level.name} {self.battery.remaining_pct:.0f}%"
            self._say(M.MAV_SEVERITY_CRITICAL, text)
            self.track.event(self.t, f"battery failsafe: {level.name}, "
                                     f"{level.action or 'a warning'}")
            if level.action == "fall":
                self._disarm(force=True, reason="battery failsafe: terminate")
            elif level.action is not None:
                self._failsafe_mode(level.action.split(" or "))

    def _failsafe_mode(self, choices) -> None:
        """The first of ``choices`` the vehicle can fly (SmartRTL only with its path),
        as ArduCopter's set_mode_SmartRTL_or_RTL / _or_land_with_pause do."""
        for mode in choices:
            if mode == self.mode:
                return
            if self.flavour.behaviour[mode] == fl.SMARTRTL and not self._smart_ok():
                self._say(M.MAV_SEVERITY_WARNING, "SmartRTL Unavailable, Trying "
                                                  f"{choices[-1].title()} Mode")
                continue
            self._set_mode(mode)
            return

    def _smart_ok(self) -> bool:
        return self.smart_path is not None and self.smart_path.active

    def _sample(self, force=False) -> None:
        lat, lon, alt = self.position()
        self.track.sample(self.t, lat, lon, alt, self.battery.used_fraction, force=force)

    def _scheduled_faults(self, now: float) -> None:
        plan = self.plan
        if plan.kill_at_s is not None and self.t >= plan.kill_at_s:
            return self._die(f"at {plan.kill_at_s:g} s")
        for k, (start, seconds) in enumerate(plan.cuts):
            if k not in self._cuts_done and self.t >= start:
                self._cuts_done.add(k)
                self.link_faults.cut(now, seconds)
                self.track.event(self.t, f"link cut for {seconds:g} s (wall)")

    def _radio_shadow(self) -> None:
        """Out of the ground station's radio line of sight, the link is cut both ways
        (looked at every `RADIO_PERIOD_S` of mission time), and the track says when."""
        if self.cfg.radio is None or self.t < self._radio_next_t:
            return
        self._radio_next_t = self.t + RADIO_PERIOD_S
        shadowed = not self.cfg.radio(*self.position())
        if shadowed != self.link_faults.shadowed:
            self.link_faults.shadowed = shadowed
            self.track.event(self.t, "out of radio contact" if shadowed
                             else "back in radio contact")

    def _link_failsafe(self, now: float) -> None:
        """The firmware's ground-station link-loss failsafe (`gcs.sim.link_loss`), once
        a cut of its link has lasted its timeout: once per cut, in the air. Timed from
        the cut, not from the ground station's last HEARTBEAT: a ground station slowed
        by its machine (its HEARTBEATs a wall second apart are 100 s of a vehicle's time
        at 100x) is not a radio that fails."""
        if not (self._heard_gcs and self.link_faults.is_cut(now)):
            self._cut_since_t, self._link_failsafe_fired = None, False
            return
        if self._cut_since_t is None:
            self._cut_since_t = self.t
        if self._link_failsafe_fired or not self.armed or self.landed:
            return
        loss = self.flavour.link_loss(self.params)
        if loss.action is None or self.t - self._cut_since_t < loss.timeout_s:
            return
        self._link_failsafe_fired = True
        if self.mode == loss.continue_in:
            self.track.event(self.t, "link failsafe: flies its mission on")
            return
        self.track.event(self.t, f"link failsafe: {loss.action}")
        if loss.action == "fall":
            self._disarm(force=True, reason="link failsafe: terminate")
        else:
            self._failsafe_mode(loss.action.split(" or "))

    def _kill_at_item(self, seq: int) -> bool:
        if self.plan.kill_at_item is not None and seq == self.plan.kill_at_item:
            self._die(f"at item {seq}")
        return self.dead

    # -- receiving --------------------------------------------------------------------
    def _receive(self, chunk: bytes, now: float) -> None:
        try:
            msgs = self.mav.parse_buffer(chunk) or []
        except M.MAVError:
            return
        for msg in msgs:
            if self.dead:
                return
            if msg.get_type() == "BAD_DATA" or not self.link_faults.passes(now):
                continue
            target = getattr(msg, "target_system", 0)
            if target not in (0, self.sysid):
                continue
            self._dispatch(msg, now)

    def _dispatch(self, msg, now: float) -> None:
        kind = msg.get_type()
        if kind == "HEARTBEAT" and msg.type == M.MAV_TYPE_GCS:
            self._heard_gcs = True
        if self.mission.handle(msg, now):
            return
        if kind in ("COMMAND_LONG", "COMMAND_INT"):
            self._on_command(msg)
        elif kind == "SET_MODE":
            result = self._set_mode_custom(msg.custom_mode)
            self._ack(M.MAVLINK_MSG_ID_SET_MODE, result, msg)
        elif kind == "MISSION_SET_CURRENT":
            self._set_current(msg.seq)
        elif kind == "SET_POSITION_TARGET_GLOBAL_INT":
            self._on_position_target(msg)
        elif kind == "REQUEST_DATA_STREAM":
            if msg.start_stop:
                self._request_streams()
        elif kind in ("PARAM_REQUEST_LIST", "PARAM_REQUEST_READ", "PARAM_SET"):
            self._on_param(msg)

    # -- commands ---------------------------------------------------------------------
    def _on_command(self, msg) -> None:
        p = [msg.param1, msg.param2, msg.param3, msg.param4]
        if msg.get_type() == "COMMAND_INT":
            scale = 1e-7 if msg.frame in GLOBAL_FRAMES else 1.0
            p += [msg.x * scale, msg.y * scale, msg.z]
            frame = msg.frame
        else:
            p += [msg.param5, msg.param6, msg.param7]
            frame = None
        handler = self._COMMANDS.get(msg.command)
        result = M.MAV_RESULT_UNSUPPORTED if handler is None else handler(self, p, frame)
        self._ack(msg.command, result, msg)

    def _ack(self, command: int, result: int, msg) -> None:
        self._send(self.mav.command_ack_encode(command, result, 0, 0, msg.get_srcSystem(),
                                               msg.get_srcComponent()))

    def _cmd_set_mode(self, p, frame) -> int:
        name = self.flavour.mode_from_command(p[1], p[2])
        return M.MAV_RESULT_FAILED if name is None else self._set_mode(name)

    def _set_mode_custom(self, custom_mode: int) -> int:
        name = self.flavour.mode_named(custom_mode)
        return M.MAV_RESULT_FAILED if name is None else self._set_mode(name)

    def _cmd_arm(self, p, frame) -> int:
        if p[0] >= 0.5:
            return self._arm()
        return self._disarm(force=int(round(p[1])) == FORCE_DISARM)

    def _cmd_takeoff(self, p, frame) -> int:
        if self.flavour.takeoff_mode is None:
            # ArduPilot: GUIDED, armed and on the ground; altitude relative to home.
            if not (self.armed and self.landed and self.behaviour() == fl.GUIDED):
                return M.MAV_RESULT_FAILED
            self._start_takeoff(self.ground + p[6])
            return M.MAV_RESULT_ACCEPTED
        alt = p[6] if math.isfinite(p[6]) else self.ground + 2.5     # PX4: AMSL
        self._takeoff_alt = alt
        return self._set_mode(self.flavour.takeoff_mode)

    def _cmd_mission_start(self, p, frame) -> int:
        auto = self.flavour.mission_mode
        if self.flavour.start_needs_armed and not self.armed:
            return M.MAV_RESULT_FAILED
        if p[0] > 0 and self.mission.item(int(p[0])) is not None:
            self.current = int(p[0])
        self.auto_started = True
        result = self._set_mode(auto)
        if result == M.MAV_RESULT_ACCEPTED and self.armed and self.task is None:
            self._run_mission(self.current)
        return result

    def _cmd_set_current(self, p, frame) -> int:
        return M.MAV_RESULT_ACCEPTED if self._set_current(int(p[0])) else M.MAV_RESULT_DENIED

    def _default_streams(self) -> None:
        """What streams before a ground station asks: everything, or (ArduPilot)
        HEARTBEAT only."""
        self._periods = dict(telemetry.STREAMS)
        if not self.flavour.ekf_status:
            for msgid in telemetry.ARDUPILOT_ONLY:
                del self._periods[msgid]
        if self.flavour.streams_on_request and not self._streams_requested:
            self._periods = {M.MAVLINK_MSG_ID_HEARTBEAT: telemetry.STREAMS[
                M.MAVLINK_MSG_ID_HEARTBEAT]}

    def _request_streams(self) -> None:
        """A ground station asked for telemetry: the default streams from now on."""
        if not self._streams_requested:
            self._streams_requested = True
            asked = self._periods
            self._default_streams()
            self._periods.update(asked)
            self._due.clear()

    def _cmd_message_interval(self, p, frame) -> int:
        msgid, interval_us = int(p[0]), p[1]
        if interval_us < 0:
            self._periods.pop(msgid, None)
        elif interval_us == 0:
            if msgid in telemetry.STREAMS:
                self._periods[msgid] = telemetry.STREAMS[msgid]
        else:
            self._periods[msgid] = interval_us * 1e-6
        self._due.pop(msgid, None)
        return M.MAV_RESULT_ACCEPTED

    def _cmd_request_message(self, p, frame) -> int:
        return self._send_by_id(int(p[0]))

    def _cmd_home(self, p, frame) -> int:
        return self._send_by_id(M.MAVLINK_MSG_ID_HOME_POSITION)

    def _cmd_version(self, p, frame) -> int:
        return self._send_by_id(M.MAVLINK_MSG_ID_AUTOPILOT_VERSION)

    def _cmd_reposition(self, p, frame) -> int:
        f = self.flavour
        if f.reposition_int_only and frame is None:
            return M.MAV_RESULT_UNSUPPORTED        # ArduPilot takes it as COMMAND_INT only
        if not self.armed or self.landed:
            return f.deny_result
        if f.reposition_needs_flag and self.behaviour() != fl.GUIDED:
            if not int(p[1]) & M.MAV_DO_REPOSITION_FLAGS_CHANGE_MODE:
                return M.MAV_RESULT_FAILED
            self._set_mode(f.guided_mode)
        elif not f.reposition_needs_flag:
            self._set_mode(f.guided_mode)
        x, y, z = self.body.pos
        if math.isfinite(p[4]) and math.isfinite(p[5]) and (p[4], p[5]) != (0.0, 0.0):
            x, y = self.frame.to_local(p[4], p[5])
        if math.isfinite(p[6]):
            z = self._alt(p[6], frame if frame is not None else M.MAV_FRAME_GLOBAL)
        if p[0] > 0:
            self.body.set_speed(p[0])
        self._go_to((x, y, z))
        return M.MAV_RESULT_ACCEPTED

    def _cmd_image_capture(self, p, frame) -> int:
        self._snapshot(None)
        return M.MAV_RESULT_ACCEPTED

    def _cmd_digicam(self, p, frame) -> int:
        if p[4] == 1:                        # param5: shoot
            self._snapshot(None)
        return M.MAV_RESULT_ACCEPTED

    def _cmd_trigger_distance(self, p, frame) -> int:
        if p[2] == 1:                        # param3: trigger once now
            self._snapshot(None)
        return M.MAV_RESULT_ACCEPTED

    def _cmd_land(self, p, frame) -> int:
        return self._set_mode(self.flavour.land_mode)

    def _cmd_rtl(self, p, frame) -> int:
        return self._set_mode(self.flavour.rtl_mode)

    def _cmd_change_speed(self, p, frame) -> int:
        if p[1] > 0:
            self.body.set_speed(p[1])
        return M.MAV_RESULT_ACCEPTED

    _COMMANDS = {
        M.MAV_CMD_DO_SET_MODE: _cmd_set_mode,
        M.MAV_CMD_COMPONENT_ARM_DISARM: _cmd_arm,
        M.MAV_CMD_NAV_TAKEOFF: _cmd_takeoff,
        M.MAV_CMD_MISSION_START: _cmd_mission_start,
        M.MAV_CMD_DO_SET_MISSION_CURRENT: _cmd_set_current,
        M.MAV_CMD_SET_MESSAGE_INTERVAL: _cmd_message_interval,
        M.MAV_CMD_REQUEST_MESSAGE: _cmd_request_message,
        M.MAV_CMD_GET_HOME_POSITION: _cmd_home,
        M.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES: _cmd_version,
        M.MAV_CMD_DO_REPOSITION: _cmd_reposition,
        M.MAV_CMD_IMAGE_START_CAPTURE: _cmd_image_capture,
        M.MAV_CMD_DO_DIGICAM_CONTROL: _cmd_digicam,
        M.MAV_CMD_DO_SET_CAM_TRIGG_DIST: _cmd_trigger_distance,
        M.MAV_CMD_NAV_LAND: _cmd_land,
        M.MAV_CMD_NAV_RETURN_TO_LAUNCH: _cmd_rtl,
        M.MAV_CMD_DO_CHANGE_SPEED: _cmd_change_speed,
    }

    def _on_position_target(self, msg) -> None:
        """SET_POSITION_TARGET_GLOBAL_INT: a position in GUIDED (ArduPilot)."""
        if msg.type_mask & 0b111 or self.behaviour() != fl.GUIDED or self.landed:
            return
        x, y = self.frame.to_local(msg.lat_int * 1e-7, msg.lon_int * 1e-7)
        self._go_to((x, y, self._alt(msg.alt, msg.coordinate_frame)))

    def _on_param(self, msg) -> None:
        names = list(self.params)
        kind = msg.get_type()
        if kind == "PARAM_SET" and msg.param_id in self.params:
            value = sim_params.value_set(self.flavour, msg)
            if value is None:               # PX4 refuses a type mismatch, unanswered
                return
            self.params[msg.param_id] = value
        if kind == "PARAM_REQUEST_LIST":
            wanted = names
        elif kind == "PARAM_REQUEST_READ" and msg.param_index >= 0:
            wanted = names[msg.param_index:msg.param_index + 1]
        else:
            wanted = [msg.param_id] if msg.param_id in self.params else []
        for name in wanted:
            wire, param_type = sim_params.wire(self.flavour, name, self.params[name])
            self._send(self.mav.param_value_encode(
                name.encode(), wire, param_type, len(names), names.index(name)))

    # -- modes, arming ----------------------------------------------------------------
    def behaviour(self) -> str:
        return self.flavour.behaviour[self.mode]

    def _set_mode(self, name: str) -> int:
        flying = self.armed and not self.landed      # a falling vehicle obeys nothing
        if self.flavour.behaviour[name] == fl.SMARTRTL and not self._smart_ok():
            return M.MAV_RESULT_FAILED              # ModeSmartRTL::init: no path
        if flying and self.behaviour() == fl.AUTO and self.flavour.behaviour[name] != fl.AUTO:
            self._left_at = self.current
        self.mode = name
        self._last_dest = None     # a resumed leg starts where the vehicle is, as AC_WPNav
        behaviour = self.behaviour()
        if behaviour != fl.AUTO:
            self.auto_started = False
        if behaviour in (fl.MANUAL, fl.GUIDED):
            if flying:
                self._go_to(self.body.pos)
        elif behaviour == fl.AUTO:
            if flying or (self.armed and self.flavour.arm_in_auto_starts):
                self._resuming = flying
                self._run_mission(self._rewound())
        elif behaviour == fl.LAND:
            if flying:
                self._start_land(None, None)
        elif behaviour == fl.RTL:
            if flying:
                self._start_rtl(None)
        elif behaviour == fl.SMARTRTL:
            if flying:
                self.task = {"kind": "retrace", "seq": None, "back": self.smart_path.way_back()}
                self._update_retrace(self.task)
        elif behaviour == fl.TAKEOFF:
            if self.armed:
                self._start_takeoff(self._takeoff_alt)
        return M.MAV_RESULT_ACCEPTED

    def _arm(self) -> int:
        if self.armed:
            return M.MAV_RESULT_ACCEPTED
        texts = self.flavour.texts
        problem = None
        if self.plan.refuse_arm:
            problem = texts.refused
        elif not self.gps_fix:
            problem = texts.no_gps
        elif not self.ready:
            problem = texts.no_ekf
        elif not self._mode_armable():
            problem = texts.bad_mode
        if problem is not None:
            self._say(M.MAV_SEVERITY_CRITICAL, problem)
            return self.flavour.deny_result
        self.armed = True
        self.smart_path = smartrtl.path_of(self.flavour, self.params, self.body.pos)
        self._idle_since = self.t
        x, y, z = self.body.pos                 # home is where the vehicle arms
        self.home = (x, y, self.ground)
        self.track.event(self.t, "armed")
        if self.behaviour() == fl.AUTO and self.flavour.arm_in_auto_starts:
            self._run_mission(self.current)
        elif self.behaviour() == fl.TAKEOFF:
            self._start_takeoff(self._takeoff_alt)
        return M.MAV_RESULT_ACCEPTED

    def _mode_armable(self) -> bool:
        if self.mode in self.flavour.armable:
            return True
        return self.mode == self.flavour.mission_mode and \
            int(self.params.get("AUTO_OPTIONS", 0)) & 1 == 1

    def _disarm(self, force: bool, reason="disarmed") -> int:
        if not self.armed:
            return M.MAV_RESULT_ACCEPTED
        if not self.landed and not force:
            return self.flavour.deny_result
        self.armed = False
        self.auto_started = False
        self.track.event(self.t, reason)
        if not self.landed:
            self.task = {"kind": "fall"}
            self.body.go_to((self.body.pos[0], self.body.pos[1], self.ground - 100.0))
        else:
            self.task = None
        return M.MAV_RESULT_ACCEPTED

    # -- tasks: what the vehicle is doing ---------------------------------------------
    def _go_to(self, dest, origin=None) -> None:
        self.task = {"kind": "goto"}
        self.body.go_to(dest, origin)

    def _start_takeoff(self, alt: float, seq=None) -> None:
        if self.landed and self.plan.spool_s > 0 and \
                (self.task or {}).get("kind") != "spool":
            self.task = {"kind": "spool", "until": self.t + self.plan.spool_s, "alt": alt,
                         "seq": seq}
            return
        x, y, z = self.body.pos
        if self.landed:
            self.landed = False
            self.track.event(self.t, "takeoff")
        self.task = {"kind": "takeoff", "alt": alt, "seq": seq}
        self.body.go_to((x, y, max(alt, z)))

    def _start_land(self, latlon, seq) -> None:
        self.task = {"kind": "land", "seq": seq, "phase": "approach"}
        x, y, z = self.body.pos
        if latlon is not None:
            x, y = self.frame.to_local(*latlon)
        self.body.go_to((x, y, z))

    def _start_rtl(self, seq) -> None:
        back = self._mission_return()
        if back:
            self.track.event(self.t, f"return along the mission ({len(back)} points)")
            self.task = {"kind": "retrace", "seq": seq, "back": back}
            return self._update_retrace(self.task)
        self.task = {"kind": "rtl", "seq": seq, "phase": "climb"}
        x, y, z = self.body.pos
        self.body.go_to((x, y, max(z, self.home[2] + self.cfg.rtl_alt_m)))

    def _mission_return(self) -> list:
        """PX4's Return with RTL_TYPE 2 or 4 (navigator/rtl.cpp init_rtl_mission_type):
        the mission's position items forward from the current one to its landing, or
        back from the one before to home, at their altitudes, ending above where it
        lands; [] for any other return (a climb and a straight line)."""
        rtl_type = int(self.params.get("RTL_TYPE", 0))
        if rtl_type not in (2, 4) or self.mission is None:     # ArduPilot has no RTL_TYPE
            return []
        items = [it for it in self.mission.items if it is not None and it.is_nav
                 and (it.x, it.y) != (0, 0)]
        land = next((it.seq for it in items if it.command == M.MAV_CMD_NAV_LAND), None)
        # the landing's start: the first DO_LAND_START, else the landing itself
        # (mavlink_mission.cpp land_start_index)
        mark = next((it.seq for it in self.mission.items if it is not None
                     and it.command == M.MAV_CMD_DO_LAND_START), land)
        cur = self.current
        # RTL_TYPE 2: forward when the mission lands; 4: whichever counts fewer items
        # (rtl.cpp reverseIsFurther: land start - current < current)
        forward = land is not None and (rtl_type == 2 or mark - cur < cur)
        if forward:
            way = [it for it in items if cur <= it.seq <= land]
        else:
            way = [it for it in reversed(items) if it.seq < cur
                   and it.command != M.MAV_CMD_NAV_LAND]
        points = [(*self.frame.to_local(it.lat, it.lon),
                   self.body.pos[2] if it.command == M.MAV_CMD_NAV_LAND
                   else self._alt(it.z, it.frame)) for it in way]
        if not forward:            # and then home, at the altitude it came to
            z = points[-1][2] if points else self.body.pos[2]
            points.append((self.home[0], self.home[1], z))
        elif points:               # the landing: approached at the last altitude
            points[-1] = (*points[-1][:2], points[-2][2] if len(points) > 1 else self.body.pos[2])
        return points

    def _update_task(self) -> None:
        task = self.task
        if task is None:
            return self._idle_check()
        kind = task["kind"]
        if kind == "spool":
            if self.t >= task["until"]:
                self._start_takeoff(task["alt"], task["seq"])
        elif kind == "takeoff":
            if abs(self.body.pos[2] - self.body.dest[2]) < TAKEOFF_TOLERANCE_M:
                self._takeoff_done(task)
        elif kind == "item":
            self._update_item(task)
        elif kind == "climb":
            if abs(self.body.pos[2] - self.body.dest[2]) < TAKEOFF_TOLERANCE_M:
                self._last_dest = list(self.body.pos)
                self._start_item(task["item"])
        elif kind == "land" and task["phase"] == "approach":
            if math.dist(self.body.pos[:2], self.body.dest[:2]) <= self.cfg.wp_radius_m:
                task["phase"] = "descend"
                x, y, z = self.body.pos
                self.body.go_to((x, y, self.ground - 1.0))   # aim below: touch down firmly
        elif kind == "rtl":
            self._update_rtl(task)
        elif kind == "retrace":
            self._update_retrace(task)

    def _takeoff_done(self, task) -> None:
        if task["seq"] is not None:
            self._last_dest = list(self.body.dest)
            return self._item_complete(task["seq"])
        x, y, z = self.body.pos
        self._go_to((x, y, task["alt"]))
        if self.behaviour() == fl.TAKEOFF:
            self.mode = self.flavour.hold_mode

    def _update_rtl(self, task) -> None:
        if self.body.distance_to_dest() > self.cfg.wp_radius_m:
            return
        if task["phase"] == "climb":
            task["phase"] = "return"
            self.body.go_to((*self._rtl_target(), self.body.pos[2]))
        elif task["phase"] == "return":
            seq = task["seq"]
            self._start_land(None, seq)

    def _rtl_target(self) -> tuple:
        """Where a plain return flies, straight: home, or the closest rally point held
        when it is closer (ArduPilot's RTL with RALLY_INCL_HOME 1, its default; PX4's
        Return with RTL_TYPE 0: the profiles' ``rally_returns``)."""
        here = self.body.pos[:2]
        best = tuple(self.home[:2])
        for lat, lon, _, _ in self.mission.rally():
            point = tuple(self.frame.to_local(lat, lon))
            if math.dist(here, point) < math.dist(here, best):
                best = point
        return best

    def _update_retrace(self, task) -> None:
        """A return along known points (ArduPilot's SmartRTL: its saved path newest
        first, mode_smart_rtl.cpp; PX4's mission-path Return): to each in turn, then
        land where the last one is."""
        if task.get("to") is not None and self.body.distance_to_dest() > self.cfg.wp_radius_m:
            return
        if not task["back"]:
            return self._start_land(None, None)
        task["to"] = task["back"].pop(0)
        self.body.go_to(task["to"])

    def _save_path(self) -> None:
        """ArduPilot saves its flown path for SmartRTL while armed, in any other mode."""
        if self.smart_path is None or not self.armed or self.landed or \
                self.flavour.behaviour[self.mode] == fl.SMARTRTL:
            return
        if self.smart_path.add(tuple(self.body.pos)):
            self._say(M.MAV_SEVERITY_WARNING, "SmartRTL deactivated: buffer full")
            self.track.event(self.t, "SmartRTL deactivated: buffer full")

    def _idle_check(self) -> None:
        """Armed on the ground with nothing to do: disarm, as both autopilots do."""
        if not (self.armed and self.landed) or self.cfg.auto_disarm_s <= 0:
            self._idle_since = self.t
            return
        if self._idle_since is None:
            self._idle_since = self.t
        if self.t - self._idle_since >= self.cfg.auto_disarm_s:
            self._say(M.MAV_SEVERITY_INFO, "Disarming motors due to inactivity")
            self._disarm(force=False, reason="disarmed (inactivity)")

    def _touch_down(self) -> None:
        self.body.pos[2] = self.ground
        self.body.vel = [0.0, 0.0, 0.0]
        self.body.hold()
        self.landed = True
        task, self.task = self.task, None
        self._sample(force=True)
        self.track.event(self.t, "landed" if task and task["kind"] != "fall" else "crashed")
        if self.armed:
            self._disarm(force=True, reason="disarmed (landed)")
        self._idle_since = self.t
        if task and task.get("seq") is not None and not self._kill_at_item(task["seq"]):
            self._report_reached(task["seq"])

    # -- the mission ------------------------------------------------------------------
    def _run_mission(self, seq: int, reached: int | None = None) -> None:
        """Execute from item `seq`: DO commands at once, up to the next nav item.
        ``reached``: a navigation item just completed whose MISSION_ITEM_REACHED
        waits for the DO commands after it (PX4 then reports the last of them)."""
        seq = max(seq, self.flavour.first_item)
        while not self.dead:
            item = self.mission.item(seq)
            if item is None:
                self._reached_after(reached)
                return self._mission_done(seq)
            self._set_current(seq, run=False)
            if item.is_nav:
                self._reached_after(reached)
                return self._start_item(item)
            if self._kill_at_item(seq):
                return
            self._do(item)
            if reached is not None:
                reached = seq
            seq += 1

    def _rewound(self) -> int:
        """Where a mission flown on starts: its current item, or on PX4 (the profile's
        `resume_rewinds`), left in the air with its camera triggering and its current
        item not set since, the position item before (MissionBase::on_activation
        re-flies that leg so as to lose no image)."""
        left, self._left_at = self._left_at, None
        if not (self.flavour.profile.resume_rewinds and self._camera_ran
                and left == self.current and left > self.flavour.first_item):
            return self.current
        for seq in range(left - 1, self.flavour.first_item - 1, -1):
            item = self.mission.item(seq)
            if item is not None and item.is_nav:
                self.track.event(self.t, f"resumed at the previous position item {seq}")
                return seq
        return self.current

    def _reached_after(self, seq) -> None:
        if seq is not None:
            self._report_reached(seq)

    def _start_item(self, item) -> None:
        cmd = item.command
        resuming, self._resuming = self._resuming, False
        x, y, z = self.body.pos
        if (item.x, item.y) != (0, 0):
            x, y = self.frame.to_local(item.lat, item.lon)
        if cmd != M.MAV_CMD_NAV_LAND and cmd != M.MAV_CMD_NAV_RETURN_TO_LAUNCH:
            z = self._alt(item.z, item.frame)
        if cmd == M.MAV_CMD_NAV_TAKEOFF:
            return self._start_takeoff(z, seq=item.seq)
        if cmd == M.MAV_CMD_NAV_LAND:
            latlon = (item.lat, item.lon) if (item.x, item.y) != (0, 0) else None
            return self._start_land(latlon, item.seq)
        if cmd == M.MAV_CMD_NAV_RETURN_TO_LAUNCH:
            return self._start_rtl(item.seq)
        if cmd not in _WAYPOINT_LIKE:          # a nav command we do not fly: done at once
            return self._item_complete(item.seq)
        if self.landed:
            self.landed = False
            self.track.event(self.t, "takeoff")
        hold = item.param1 if cmd in (M.MAV_CMD_NAV_WAYPOINT, M.MAV_CMD_NAV_LOITER_TIME) \
            else math.inf if cmd == M.MAV_CMD_NAV_LOITER_UNLIM else 0.0
        climb = self.flavour.profile.resume_climbs_above_m
        if resuming and climb is not None and z > self.body.pos[2] + climb:
            # PX4 (MissionBase::checkClimbRequired): straight up first, where it is
            self.track.event(self.t, f"climbs to {z:.1f} m where it is before item {item.seq}")
            self.task = {"kind": "climb", "item": item}
            return self.body.go_to((*self.body.pos[:2], z))
        origin = self._last_dest if self._last_dest is not None else self.body.pos
        self.task = {"kind": "item", "seq": item.seq, "arrived": None, "hold": max(hold, 0.0)}
        self.body.go_to((x, y, z), origin)

    def _update_item(self, task) -> None:
        if task["arrived"] is None:
            if self.body.distance_to_dest() > self.cfg.wp_radius_m:
                return
            if self._kill_at_item(task["seq"]):
                return
            task["arrived"] = self.t
            task["hold"] += self._stop_beyond_s()
        if self.t - task["arrived"] >= task["hold"]:
            self._last_dest = list(self.body.dest)
            self._item_complete(task["seq"], killed_checked=True)

    def _stop_beyond_s(self) -> float:
        """What the firmware's way of passing a waypoint costs beyond the point
        mass's, stood at the waypoint: PX4's jerk-limited stop (`Limits.jerk_mps3`),
        as `planner.rates.waypoint_stop_s` counts it; nothing for ArduPilot."""
        jerk = self.limits.jerk_mps3
        if not jerk:
            return 0.0
        v, a = self.body.speed_mps, self.limits.accel_mps2
        return waypoint_stop_s(v, a, jerk) - waypoint_stop_s(v, a)

    def _item_complete(self, seq: int, killed_checked=False) -> None:
        if not killed_checked and self._kill_at_item(seq):
            return
        if self.flavour.reached_after_do_items:
            return self._run_mission(seq + 1, reached=seq)
        self._report_reached(seq)
        self._run_mission(seq + 1)

    def _report_reached(self, seq: int) -> None:
        self.track.event(self.t, f"reached {seq}")
        if self.flavour.says_reached:
            self._say(M.MAV_SEVERITY_INFO, f"Reached command #{seq}")
        self._send(self.mav.mission_item_reached_encode(seq))

    def _mission_done(self, seq: int) -> None:
        self._last_dest = None
        if not self.landed:
            # hold where the mission ended: ArduCopter loiters in AUTO, PX4 switches
            # to AUTO.LOITER
            if self.flavour.holds_in_hold_mode:
                self.mode = self.flavour.hold_mode
            self._go_to(self.body.pos)
        else:
            self.task = None
        self.track.event(self.t, "mission complete")

    def _do(self, item) -> None:
        if item.command == M.MAV_CMD_DO_CHANGE_SPEED and item.param2 > 0:
            self.body.set_speed(item.param2)
        elif item.command == M.MAV_CMD_DO_DIGICAM_CONTROL and item.param5 == 1:
            self._snapshot(item.seq)
        elif item.command == M.MAV_CMD_IMAGE_START_CAPTURE:
            self._camera_ran = True
            self._snapshot(item.seq)
        elif item.command == M.MAV_CMD_DO_SET_CAM_TRIGG_DIST and item.param3 == 1:
            self._snapshot(item.seq)

    def _set_current(self, seq: int, run=True) -> bool:
        """MISSION_SET_CURRENT / DO_SET_MISSION_CURRENT; in AUTO in the air, go there now."""
        first = self.flavour.first_item
        if self.flavour.home_item and seq == 0:
            seq = first
        if self.mission.item(seq) is None or seq < first:
            return False
        self.current = seq
        self._send(telemetry.mission_current(self))
        if run:
            self._left_at = None        # set by the ground station: no rewind (PX4)
            self._last_dest = None
            if self.behaviour() == fl.AUTO and not self.landed and self.armed:
                self._run_mission(seq)
        return True

    def _mission_changed(self, kind: str) -> None:
        self.track.event(self.t, f"mission {kind}")
        self._left_at, self._camera_ran = None, False
        if not self.flavour.resume_old_index:
            self.current = self.flavour.first_item
            if self.behaviour() == fl.AUTO and not self.landed:
                self._last_dest = None
                self._run_mission(self.current)

    def _snapshot(self, seq) -> None:
        lat, lon, alt = self.position()
        self._images += 1
        self.track.snapshot(self.t, lat, lon, alt, seq)
        if not self.cfg.camera:
            return
        ms = int(self.t * 1000)
        rel = alt - self.home[2]
        if self.flavour.camera_feedback:
            self._send(self.mav.camera_feedback_encode(
                ms * 1000, self.sysid, 0, self._images, round(lat * 1e7), round(lon * 1e7),
                alt, rel, 0.0, 0.0, self.heading, 0.0, M.CAMERA_FEEDBACK_PHOTO, self._images))
        else:
            self._send(self.mav.camera_image_captured_encode(
                ms, 0, 0, round(lat * 1e7), round(lon * 1e7), round(alt * 1000), round(rel * 1000),
                [1.0, 0.0, 0.0, 0.0], self._images - 1, 1, b""))

    def _alt(self, z: float, frame: int) -> float:
        """A command's altitude in metres AMSL (terrain frames: the flat simulated ground)."""
        if frame in (M.MAV_FRAME_GLOBAL, M.MAV_FRAME_GLOBAL_INT):
            return float(z)
        if frame == M.MAV_FRAME_MISSION:
            return self.body.pos[2]
        return self.home[2] + float(z)

    def home_geo(self) -> tuple:
        lat, lon = self.frame.to_geo(self.home[0], self.home[1])
        return lat, lon, self.home[2]

    # -- sending ----------------------------------------------------------------------
    def _send(self, msg) -> None:
        if not self.dead:
            self.mav.send(msg)

    def _say(self, severity: int, text: str) -> None:
        self._send(self.mav.statustext_encode(severity, text.encode()[:50]))

    def _announce_ready(self) -> None:
        if self._ready_announced or not self.ready:
            return
        self._ready_announced = True
        self._say(M.MAV_SEVERITY_INFO, self.flavour.texts.ready)
        self._send_by_id(M.MAVLINK_MSG_ID_HOME_POSITION)

    def _stream(self, now: float) -> None:
        if self.link.accepted != self._clients_seen:      # greet a new TCP client now
            self._clients_seen = self.link.accepted
            self._due.clear()
        for msgid, period in list(self._periods.items()):
            if now >= self._due.get(msgid, 0.0):
                self._due[msgid] = now + period
                self._send_by_id(msgid)

    def _send_by_id(self, msgid: int) -> int:
        build = telemetry.BUILDERS.get(msgid)
        if build is None:
            return M.MAV_RESULT_DENIED
        if msgid == M.MAVLINK_MSG_ID_HOME_POSITION and not self.ready:
            return M.MAV_RESULT_DENIED          # home is set once the EKF has a position
        if msgid == M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT and not self.has_origin \
                and not self.flavour.zero_position:
            return M.MAV_RESULT_DENIED          # PX4: no global position before the EKF
        self._send(build(self))
        return M.MAV_RESULT_ACCEPTED
