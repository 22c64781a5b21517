"""End-to-end fixtures: plans on the sample terrain, and a fleet to fly them.

The fleet is the built-in simulator (`gcs.sim`), or real SITL when the
environment names its binary; the tests start and stop it themselves:

- ``ARDUPILOT_SITL_BIN`` (or ``ARDUPILOT_SITL``): an ``arducopter`` binary, started
  per vehicle as ``arducopter --model + --speedup S --defaults PARAMS,camera.parm
  -I i --sysid i+1 --home LAT,LON,ALT,0`` in a scratch working directory (it
  writes eeprom.bin, logs/, terrain/ there), ``ARDUPILOT_DEFAULTS`` naming its
  parameter file (Tools/autotest/default_params/copter.parm; optional), and
  ``CAM1_TYPE 1`` (and ``CAM2_TYPE 0``) so that it reports where its camera fires,
  and for a plan with an endurance ``BATT_CAPACITY`` of a pack that lasts it;
- ``PX4_SITL_BIN`` (or ``PX4_SITL``): the ``px4`` binary of a ``px4_sitl_default``
  build, started per vehicle as ``px4 -i i -d -w SCRATCH PX4_SITL_DIR/etc`` with
  the SIH simulator (``PX4_SYS_AUTOSTART=10040 PX4_SIMULATOR=sihsim HEADLESS=1``),
  ``PX4_HOME_LAT/LON/ALT`` at the launch point, ``PX4_SIM_SPEED_FACTOR`` and
  ``TRIG_MODE 1`` (camera feedback), and for a plan with an endurance a simulated
  battery that lasts it (``SIM_BAT_DRAIN``); ``PX4_SITL_DIR`` is the build folder
  (default: the binary's parent's parent). Instance i talks to the ground
  station from UDP 18570+i to 14550.

With a radio (``start_backend(radio=...)``), each real SITL link passes through
`relay.Relay`, which cuts it while the autopilot's own reported position is
out of the plan's radio line of sight; the simulator cuts its own.

Tests parametrised over ``backend`` run once per backend; a real backend whose
binary is not named is skipped with that reason. Flights are judged from what
the vehicles really flew: the simulator's recorded true track, or for real SITL
what the autopilot reports of itself on its second link (`judge.Judge`:
ArduPilot TCP 5762+10i, PX4's onboard link UDP 14540+i), never from what the
ground station believes.

Real SITL flies a smaller plan than the simulator (3 vehicles on a 4 km window,
at 10x for ArduPilot and 4x for PX4, whose SIH takes about 0.4 of a core per
vehicle at 4x), to keep the wall time down; see the README for the times.
"""


import os
import shutil
import signal
import subprocess
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from affine import Affine
from judge import Judge
from relay import Relay

from gcs.mavlink import M
from planner.exposure import sample_outposts
from planner.pipeline import plan_mission, prepare
from planner.plan import TERRAIN_FILE, Plan
from planner.scenario import Scenario
from planner.terrain import Terrain, sample_terrain, write_terrain


@dataclass(frozen=True)
class Setting:
    """A planning problem on a window of the sample terrain."""
    vehicles: int
    resolution_m: float
    crop: tuple                    # row, col, size of the window (cells)
    sensor_range_m: float
    extra: tuple = ()              # more Scenario fields, as (name, value) pairs
    bases: int = 1                 # launch points, the vehicles shared out among them


#: the simulator: 4 vehicles on an 8 km window with 2 outposts
SIM = Setting(4, 100.0, (190, 130, 80), 1000.0)
#: real SITL: 3 vehicles on a 4 km window with 1 outpost (flights of 10-20 min
#: of simulated time)
REAL = Setting(3, 100.0, (215, 130, 40), 1200.0)
#: one route longer than ArduPilot SITL's 650 items (after merging): a 4.5 km window
#: at 50 m, a 100 m sensor, viewpoints 50 m apart: 429 snapshots (2026-11-28; the
#: 3 km window with a 150 m sensor of before came to 203 snapshots and 375 items
#: once the search dropped redundant ones, and fitted in one upload)
LONG = Setting(1, 50.0, (430, 260, 90), 100.0,
               (("viewpoint_spacing_m", 50.0), ("speed_mps", 15.0)))
VEHICLES = SIM.vehicles
SPEEDUP = {"sim": 100.0, "sim-px4": 100.0, "ardupilot": 10.0, "px4": 4.0}

ARDUPILOT_BIN = os.environ.get("ARDUPILOT_SITL_BIN") or os.environ.get("ARDUPILOT_SITL")
PX4_BIN = os.environ.get("PX4_SITL_BIN") or os.environ.get("PX4_SITL")
REAL_BACKENDS = ("ardupilot", "px4")
#: what ArduPilot SITL's copter draws, by its battery monitor, per minute of a
#: sortie (climb to the hidden ceiling included: a 5980 mAh pack came down to 25 %
#: after 7.5-minute sorties; 3300 mAh went 1.5-1.6 times faster than a 10-minute
#: rating), and the spare a pack sized for a plan's endurance gets
SITL_DRAW_MAH_PER_MIN, PACK_HEADROOM = 600.0, 1.15


# -- the plan ------------------------------------------------------------------------
def cropped_sample(setting: Setting = SIM) -> tuple:
    """A window of the built-in sample terrain and the sample outposts inside it."""
    full = sample_terrain(resolution=setting.resolution_m)
    r0, c0, n = setting.crop
    window = (slice(r0, r0 + n), slice(c0, c0 + n))
    terrain = Terrain(full.height[window].copy(), full.transform @ Affine.translation(c0, r0),
                      full.crs, "sample terrain window", height_upper=full.upper[window].copy(),
                      source_surface=full.source_surface)
    outposts = [o for o in sample_outposts(full) if terrain.contains_xy(o.x, o.y)]
    return terrain, outposts


#: a second base stands at least this far (m) from the first (at 800 m the sample's
#: window has one 11 m above it; at 1.5 km, 61 m)
BASES_APART_M = 800.0


def launch_points(terrain, outposts, setting: Setting = SIM) -> list:
    """One (lat, lon) per vehicle: `launch_point`, and with two ``bases`` the cell of
    its region at least `BASES_APART_M` from it whose ground is nearest its height
    (real SITL's ground is flat at each vehicle's home: a base at another height
    would be landed at in the air, or under the DEM), the vehicles taking turns."""
    first = launch_point(terrain, outposts, setting)
    if setting.bases == 1:
        return [first]
    rows, cols = _region_cells(terrain, outposts, setting)
    fx, fy = terrain.from_lonlat(first[1], first[0])
    x, y = terrain.xy(rows, cols)
    far = np.hypot(np.asarray(x) - fx, np.asarray(y) - fy) >= BASES_APART_M
    ground = terrain.ground(fx, fy, upper=True)[0]
    i = int(np.argmin(np.where(far, np.abs(terrain.height[rows, cols] - ground), np.inf)))
    lon, lat = terrain.to_lonlat(*terrain.xy(rows[i], cols[i]))
    return [first, (float(lat), float(lon))] * (setting.vehicles // 2) + \
        [first] * (setting.vehicles % 2)


def _region_cells(terrain, outposts, setting) -> tuple:
    """(rows, cols) of the largest hidden region's cells, off the edge."""
    ctx = prepare(Scenario(sample=True, uavs=setting.vehicles,
                           sensor_range_m=setting.sensor_range_m).validate(),
                  terrain=terrain, outposts=outposts)
    regions = ctx.surface.regions
    sizes = np.bincount(regions.ravel())
    sizes[0] = 0
    rows, cols = np.nonzero(regions == np.argmax(sizes))
    n = terrain.shape[0]
    keep = (rows > 3) & (cols > 3) & (rows < n - 4) & (cols < n - 4)
    return rows[keep], cols[keep]


def launch_point(terrain, outposts, setting: Setting = SIM) -> tuple:
    """(lat, lon) of the lowest flyable cell of the largest hidden region, off the edge.

    Lowest, so that real SITL's flat ground (at the home altitude) lies below
    everything the plan flies over."""
    rows, cols = _region_cells(terrain, outposts, setting)
    i = int(np.argmin(terrain.height[rows, cols]))
    lon, lat = terrain.to_lonlat(*terrain.xy(rows[i], cols[i]))
    return float(lat), float(lon)


def make_plan(directory: Path, k: int, setting: Setting = SIM) -> Path:
    """Plan a window of the sample terrain and write what `gcs plan` writes for fly."""
    terrain, outposts = cropped_sample(setting)
    scenario = Scenario(sample=True, uavs=setting.vehicles, k=k,
                        sensor_range_m=setting.sensor_range_m,
                        launch=launch_points(terrain, outposts, setting),
                        **dict(setting.extra)).validate()
    ctx, outcome = plan_mission(scenario, terrain=terrain, outposts=outposts)
    directory.mkdir(parents=True, exist_ok=True)
    outcome.plan.save(directory)
    write_terrain(directory / TERRAIN_FILE, ctx.terrain)
    ctx.save(directory)
    return directory



class SimBackend:
    """The built-in simulated ArduPilot copters; tracks recorded by the simulator."""

    name = "sim"
    firmware = "ardupilot"

    def __init__(self, plan: Plan, workdir: Path, speedup: float, capacity=None,
                 below_base_m=0.0, spool=None, radio=None, params=None):
        from gcs.sim import FaultPlan, FleetConfig, SimFleet, free_fleet_ports
        from gcs.sim.physics import Limits

        homes = list(homes_of(plan, below_base_m).values())
        self.track_dir = workdir / "tracks"
        self.fleet = SimFleet(FleetConfig(
            vehicles=len(homes), firmware=self.firmware, homes=homes, speedup=speedup,
            track_dir=self.track_dir, warmup_s=1.0, auto_disarm_s=50.0 * speedup,
            limits=Limits(speed_mps=plan.params["speed_mps"]),   # the firmware's vertical rates
            faults={sysid: FaultPlan(spool_s=s) for sysid, s in (spool or {}).items()},
            radio=radio,
            **({} if capacity is None else {"mission_capacity": capacity}),
            **free_fleet_ports(self.firmware, len(homes)))).start()
        # auto-disarm runs on the simulated clock: at 100x, ArduPilot's 10 s would be
        # 0.1 s of wall time, shorter than one command retry on a lossy link
        self.boot_unix = time.time()

    def urls(self) -> list:
        return self.fleet.urls()

    def set_drop(self, pct: float) -> None:
        self.fleet.set_drop(pct)

    def kill(self, sysid: int) -> float:
        """Shoot a vehicle down; returns the wall time (time.time()) it went silent."""
        self.fleet.kill(sysid)
        return time.time()

    def cut_link(self, sysid: int, seconds: float) -> None:
        """Cut ``sysid``'s link both ways for ``seconds`` of wall time."""
        self.fleet.cut_link(sysid, seconds)

    def tracks(self, flight_dir: Path) -> dict:
        """{sysid: (t, lat, lon, alt, snapshots [(lat, lon, alt)], home (lat, lon, alt))},
        t on the wall clock (Unix s), which the vehicles share, as the judges' do."""
        from gcs.sim import read_track, track_path

        out = {}
        for v in self.fleet.vehicles:
            tr = read_track(track_path(self.track_dir, v.sysid))
            snaps = [(s["lat"], s["lon"], s["alt"]) for s in tr.snapshots]
            out[v.sysid] = (tr.wall, tr.lat, tr.lon, tr.alt, snaps, tr.home)
        return out

    def hold_on_ground(self, sysid: int, hold: bool = True) -> None:
        """Refuse (or allow again) the arming of ``sysid``: it starts late."""
        self.fleet.refuse_arm(sysid, hold)

    def stop(self) -> None:
        self.fleet.stop()


class ProcessBackend:
    """Real SITL processes, one per vehicle, each watched by a `judge.Judge` on its
    second link; a kill is a SIGKILL of the process."""

    def __init__(self, plan: Plan, workdir: Path, speedup: float, capacity=None,
                 below_base_m=0.0, spool=None, radio=None, params=None):
        self.plan = plan
        self.params = params or {}
        self.workdir = workdir
        self.procs, self.judges = {}, {}
        self.homes = homes_of(plan, below_base_m)
        self.relay = None
        try:
            for sysid, home in self.homes.items():
                self.procs[sysid] = self._start(sysid - 1, home, speedup)
            self._ready()
            if radio is not None:
                self.relay = Relay(self.judges, radio)
                self._relay()
        except BaseException:
            self.stop()
            raise

    def _ready(self) -> None:
        """Wait until the ground station can connect."""

    def set_drop(self, pct: float) -> None:
        raise NotImplementedError("packet loss is injected by the simulated vehicles only")

    def kill(self, sysid: int) -> float:
        proc = self.procs[sysid]
        os.killpg(proc.pid, signal.SIGKILL)
        t = time.time()
        proc.wait(timeout=10)
        return t

    def _relay(self) -> None:
        """Put `relay.Relay` between the ground station and each vehicle."""

    def cut_link(self, sysid: int, seconds: float) -> None:
        """Cut ``sysid``'s link both ways for ``seconds`` of wall time (at the relay:
        started with ``radio``)."""
        self.relay.cut_for(sysid, seconds)

    def stop(self) -> None:
        if self.relay is not None:
            self.relay.stop()
        for judge in self.judges.values():
            judge.stop()
        for proc in self.procs.values():
            if proc.poll() is None:
                try:
                    os.killpg(proc.pid, signal.SIGTERM)
                    proc.wait(timeout=10)
                except (subprocess.TimeoutExpired, ProcessLookupError):
                    pass
            if proc.poll() is None:
                try:
                    os.killpg(proc.pid, signal.SIGKILL)
                except ProcessLookupError:
                    pass
                proc.wait(timeout=10)

    def tracks(self, flight_dir: Path) -> dict:
        """What each autopilot reported of itself on its second link (also written to
        ``flight_dir/judge_<sysid>.json``)."""
        import json

        out = {sysid: judge.track() for sysid, judge in sorted(self.judges.items())}
        for sysid, (t, lat, lon, alt, shots, home) in out.items():
            (flight_dir / f"judge_{sysid}.json").write_text(json.dumps({
                "samples": np.stack([t, lat, lon, alt], axis=1).tolist(), "shots": shots,
                "home": home}))
        return out

    def _popen(self, cmd, cwd, env=None):
        log = open(cwd / "sitl.log", "wb")
        return subprocess.Popen(cmd, cwd=cwd, env=env, stdout=log, stderr=subprocess.STDOUT,
                                stdin=subprocess.DEVNULL, start_new_session=True)


class ArduPilotBackend(ProcessBackend):
    name = "ardupilot"
    firmware = "ardupilot"

    def _start(self, i, home, speedup):
        lat, lon, alt = home
        cwd = self.workdir / f"ardupilot_{i}"
        cwd.mkdir(parents=True, exist_ok=True)
        # the camera reports where it fires (CAMERA_FEEDBACK); CAM2_TYPE too, or
        # ArduPilot's parameter conversion from CAM_TRIGG_TYPE resets CAM1_TYPE to 0
        camera = cwd / "camera.parm"
        camera.write_text("CAM1_TYPE 1\nCAM2_TYPE 0\n" + self._battery() +
                          "".join(f"{k} {v:g}\n" for k, v in self.params.items()))
        defaults = [os.environ["ARDUPILOT_DEFAULTS"]] if os.environ.get("ARDUPILOT_DEFAULTS") \
            else []
        cmd = [ARDUPILOT_BIN, "--model", "+", "--speedup", str(speedup),
               "--defaults", ",".join(defaults + [str(camera)]), "-I", str(i),
               "--sysid", str(i + 1),
               "--home", f"{lat},{lon},{alt},0"]
        return self._popen(cmd, cwd)

    def _battery(self) -> str:
        """A pack that lasts the plan's endurance at SITL's own draw, with
        `PACK_HEADROOM` to spare (the battery watch brings home a vehicle drawing
        faster than rated), or without one its longest flight: SITL's default
        3300 mAh lasts about 6.3 min, and reported empty mid-mission on a plan
        without an endurance (a problem of the flight's outcome; once a vehicle
        landed on its low-battery failsafe as a re-plan held it). Twice the longest:
        a re-plan gives the survivors a lost vehicle's work."""
        minutes = self.plan.params.get("endurance_min") or \
            2.0 * max((v.mission_time_s for v in self.plan.vehicles), default=0.0) / 60.0
        if not minutes:
            return ""
        return f"BATT_CAPACITY {minutes * SITL_DRAW_MAH_PER_MIN * PACK_HEADROOM:.0f}\n"

    def _ready(self) -> None:
        """Its first port listening (without connecting: the first client takes it);
        each judge connects to the second port once the ground station has
        connected to the first (only then does it open)."""
        from judge import wait_listening

        for sysid, proc in self.procs.items():
            wait_listening(5760 + 10 * (sysid - 1), 30.0, lambda: proc.poll() is None)
            self.judges[sysid] = Judge.ardupilot(sysid, self.homes[sysid],
                                                 5762 + 10 * (sysid - 1),
                                                 lambda p=proc: p.poll() is None)

    def _relay(self) -> None:
        self.relay_ports = [self.relay.tcp(sysid, 5760 + 10 * (sysid - 1))
                            for sysid in sorted(self.procs)]

    def urls(self) -> list:
        if self.relay is not None:
            return [f"tcp:127.0.0.1:{port}" for port in self.relay_ports]
        return [f"tcp:127.0.0.1:{5760 + 10 * i}" for i in range(len(self.procs))]

    def hold_on_ground(self, sysid: int, hold: bool = True) -> None:
        """Refuse (or allow again) the arming of ``sysid``, as a pre-arm check does
        until the vehicle is ready: BATT_ARM_VOLT above the pack's voltage ("PreArm:
        Battery 1 below minimum arming voltage")."""
        self.judges[sysid].set_param("BATT_ARM_VOLT", 100.0 if hold else 0.0)

    def swap_battery(self, sysid: int) -> None:
        """The crew's battery swap between sorties: the monitor's consumed charge reset
        to a full pack (MAV_CMD_BATTERY_RESET, first battery, 100 %), sent on the
        judge's link, which the ground station never sees."""
        self.judges[sysid].command(M.MAV_CMD_BATTERY_RESET, 1, 100)

    def reboot(self, sysid: int) -> None:
        """The crew's battery swap with the autopilot powered down, as on a flight
        controller fed by its pack: SITL rebooted (it runs itself again, its ports
        closed meanwhile, its battery full; its parameters and mission kept)."""
        self.judges[sysid].command(M.MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN, 1)


class Px4Backend(ProcessBackend):
    name = "px4"
    firmware = "px4"

    def _start(self, i, home, speedup):
        lat, lon, alt = home
        binary = Path(PX4_BIN).resolve()
        build = Path(os.environ.get("PX4_SITL_DIR") or binary.parents[1])
        cwd = self.workdir / f"px4_{i}"
        shutil.rmtree(cwd, ignore_errors=True)
        cwd.mkdir(parents=True)
        sysid = i + 1
        self.judges[sysid] = Judge.px4(sysid, self.homes[sysid], 14540 + i, 14580 + i)
        env = dict(os.environ, PX4_SYS_AUTOSTART="10040", PX4_SIMULATOR="sihsim", HEADLESS="1",
                   PX4_HOME_LAT=repr(lat), PX4_HOME_LON=repr(lon),
                   PX4_HOME_ALT=repr(alt), PX4_SIM_SPEED_FACTOR=str(speedup),
                   PX4_PARAM_TRIG_MODE="1", **self._battery(),
                   **{f"PX4_PARAM_{k}": f"{v:g}" for k, v in self.params.items()})
        env.pop("PX4_SIM_MODEL", None)
        return self._popen([str(binary), "-i", str(i), "-d", "-w", str(cwd),
                            str(build / "etc")], cwd, env)

    def _battery(self) -> dict:
        """A plan with an endurance gets a simulated pack that lasts it with
        `PACK_HEADROOM` to spare, drawn down to empty (PX4's BatterySimulator drains
        linearly over ``SIM_BAT_DRAIN`` armed seconds, by default 60, and stops at
        ``SIM_BAT_MIN_PCT``, by default 50 %)."""
        endurance = self.plan.params.get("endurance_min")
        if not endurance:
            return {}
        return {"PX4_PARAM_SIM_BAT_DRAIN": f"{endurance * 60 * PACK_HEADROOM:.0f}",
                "PX4_PARAM_SIM_BAT_MIN_PCT": "0"}

    def hold_on_ground(self, sysid: int, hold: bool = True) -> None:
        """Refuse (or allow again) the arming of ``sysid``: COM_ARMABLE 0 (commander
        denies every arming while it is 0)."""
        self.judges[sysid].set_param("COM_ARMABLE", 0 if hold else 1, integer=True)

    def swap_battery(self, sysid: int) -> None:
        """Nothing for the crew to do: PX4 SITL's simulated battery is full again
        whenever the vehicle is disarmed (BatterySimulator), which it is once landed."""

    def _relay(self) -> None:
        from gcs.sim import free_base_port

        self.gcs_port = free_base_port(udp=True)
        self.relay.udp(14550, self.gcs_port)

    def urls(self) -> list:
        return [f"udpin:0.0.0.0:{self.gcs_port if self.relay is not None else 14550}"]


class SimPx4Backend(SimBackend):
    """The built-in simulated copters with PX4's modes, start sequence and UDP ports."""

    name = "sim-px4"
    firmware = "px4"


BACKENDS = {"sim": (SimBackend, None), "sim-px4": (SimPx4Backend, None),
            "ardupilot": (ArduPilotBackend, ARDUPILOT_BIN), "px4": (Px4Backend, PX4_BIN)}


def skip_unless_configured(name: str) -> None:
    cls, binary = BACKENDS[name]
    if name in REAL_BACKENDS and not binary:
        var = "ARDUPILOT_SITL_BIN" if name == "ardupilot" else "PX4_SITL_BIN"
        pytest.skip(f"real {name} SITL not configured: set {var} to its binary")



def start_backend(name: str, plan: Plan, workdir: Path, speedup: float | None = None,
                  capacity=None, below_base_m=0.0, spool=None, radio=None, params=None):
    """``below_base_m``: each vehicle's home (its simulated ground) that much below its
    base, a column longer than planned; ``spool``: {sysid: s} it stays on the ground
    after its takeoff is commanded (the built-in simulator); ``radio``: (lat, lon,
    alt AMSL) -> heard, each link cut while it says False (`gcs.sim.radio_for_plan`:
    the simulator's own radio; real SITL: `relay.Relay` on the autopilot's own
    reported position); ``params``: {name: value} real SITL starts with (its
    defaults otherwise)."""
    cls, _ = BACKENDS[name]
    return cls(plan, workdir, speedup or SPEEDUP[name], capacity, below_base_m, spool, radio,
               params)


def homes_of(plan: Plan, below_base_m=0.0) -> dict:
    """{sysid: (lat, lon, ground m AMSL)}: each vehicle at its route's launch point,
    its ground ``below_base_m`` lower (SITL's flat ground below the planned base: the
    column it climbs is that much longer than the plan's)."""
    return {i + 1: (v.launch.lat, v.launch.lon, v.launch.alt_amsl - below_base_m)
            for i, v in enumerate(plan.vehicles)}


#: wall seconds a real-SITL test may take (a flight of up to ~40 min of simulated
#: time at 4x, its boot and its uploads), instead of the file's own timeout
