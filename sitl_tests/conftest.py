"""End-to-end fixtures: one plan per session on the sample terrain, and a fleet to fly it.

The fleet is the built-in simulator (`gcs.sim`) unless the environment names a
real SITL binary:

- ``ARDUPILOT_SITL_BIN`` (or ``ARDUPILOT_SITL``): an ``arducopter`` binary, started
  per vehicle as ``arducopter --model + --speedup S --defaults PARAMS -I i
  --sysid i+1 --home LAT,LON,ALT,0`` in its own working directory, with
  ``ARDUPILOT_DEFAULTS`` naming the parameter file (optional);
- ``PX4_SITL_BIN`` (or ``PX4_SITL``): a ``px4`` binary of a ``px4_sitl_default``
  build, started from ``PX4_SITL_DIR`` (default: four folders above the binary,
  the PX4 source folder) with the SIH simulator, instance i on UDP 18570+i
  sending to 14550.

Tests parametrised over ``backend`` run once per backend; a real backend not
named in the environment is skipped with that reason. Vehicles are judged
from what they really flew: the simulator's recorded track, or for real SITL the
positions the vehicle itself reported in its .tlog.
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

from planner.context import PlanningContext
from planner.exposure import sample_outposts
from planner.pipeline import plan_mission, prepare
from planner.plan import TERRAIN_FILE, Plan
from planner.scenario import Scenario
from planner.terrain import Terrain, sample_terrain, write_terrain

VEHICLES = 4
RESOLUTION_M = 100.0          # coarse: the whole plan takes a few seconds
CROP = (190, 130, 80)         # row, col, size of the sample-terrain window (8 km, 2 outposts)
SENSOR_RANGE_M = 1000.0
SPEEDUP = {"sim": 100.0, "sim-px4": 100.0, "ardupilot": 10.0, "px4": 10.0}

ARDUPILOT_BIN = os.environ.get("ARDUPILOT_SITL_BIN") or os.environ.get("ARDUPILOT_SITL")
PX4_BIN = os.environ.get("PX4_SITL_BIN") or os.environ.get("PX4_SITL")


# -- the plan ------------------------------------------------------------------------
def cropped_sample() -> tuple:
    """A window of the built-in sample terrain and the sample outposts inside it."""
    full = sample_terrain(resolution=RESOLUTION_M)
    r0, c0, n = CROP
    window = (slice(r0, r0 + n), slice(c0, c0 + n))
    terrain = Terrain(full.height[window].copy(), full.transform @ Affine.translation(c0, r0),
                      full.crs, "sample terrain window", height_upper=full.upper[window].copy(),
                      source_surface=full.source_surface)
    outposts = [o for o in sample_outposts(full) if terrain.contains_xy(o.x, o.y)]
    return terrain, outposts


def launch_point(terrain, outposts) -> tuple:
    """(lat, lon) of the lowest flyable cell of the largest hidden region, off the edge.

    Lowest, so that real ArduPilot SITL's flat ground (at the home altitude) lies
    below everything the plan flies over."""
    ctx = prepare(Scenario(sample=True, uavs=VEHICLES, sensor_range_m=SENSOR_RANGE_M)
                  .validate(), terrain=terrain, outposts=outposts)
    regions = ctx.surface.regions
    sizes = np.bincount(regions.ravel())
    sizes[0] = 0
    rows, cols = np.nonzero(regions == np.argmax(sizes))
    n = terrain.shape[0]
    keep = (rows > 3) & (cols > 3) & (rows < n - 4) & (cols < n - 4)
    rows, cols = rows[keep], cols[keep]
    i = int(np.argmin(terrain.height[rows, cols]))
    lon, lat = terrain.to_lonlat(*terrain.xy(rows[i], cols[i]))
    return float(lat), float(lon)


def make_plan(directory: Path, k: int) -> Path:
    """Plan the sample window for 4 vehicles and write what `gcs plan` writes for fly."""
    terrain, outposts = cropped_sample()
    scenario = Scenario(sample=True, uavs=VEHICLES, k=k, sensor_range_m=SENSOR_RANGE_M,
                        launch=[launch_point(terrain, outposts)]).validate()
    ctx, outcome = plan_mission(scenario, terrain=terrain, outposts=outposts)
    directory.mkdir(parents=True, exist_ok=True)
    outcome.plan.save(directory)
    write_terrain(directory / TERRAIN_FILE, ctx.terrain)
    ctx.save(directory)
    return directory


@dataclass
class Planned:
    directory: Path
    plan: Plan
    ctx: object      # PlanningContext rebuilt from the directory (sensor model, targets)
    surface: object  # the plan's true exposure surface (outposts exactly as planned)


@pytest.fixture(scope="session")
def planned(tmp_path_factory):
    """{k: Planned} for k = 0 and 1, planned once per session."""
    out = {}
    for k in (0, 1):
        d = make_plan(tmp_path_factory.mktemp(f"plan_k{k}"), k)
        plan = Plan.load(d)
        ctx = PlanningContext.load(d, plan)
        out[k] = Planned(d, plan, ctx, ctx.surface)
    return out


# -- fleets --------------------------------------------------------------------------
class SimBackend:
    """The built-in simulated ArduPilot copters; tracks recorded by the simulator."""

    name = "sim"
    firmware = "ardupilot"

    def __init__(self, plan: Plan, workdir: Path, speedup: float):
        from gcs.sim import FleetConfig, SimFleet, free_fleet_ports

        homes = [(v.launch.lat, v.launch.lon, v.launch.alt_amsl) for v in plan.vehicles]
        self.track_dir = workdir / "tracks"
        self.fleet = SimFleet(FleetConfig(
            vehicles=len(homes), firmware=self.firmware, homes=homes, speedup=speedup,
            track_dir=self.track_dir, warmup_s=1.0, auto_disarm_s=50.0 * speedup,
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

    def tracks(self, flight_dir: Path) -> dict:
        """{sysid: (t, lat, lon, alt, snapshots [(lat, lon, alt)], home (lat, lon, alt))}."""
        from gcs.sim import read_track, track_path

        out = {}
        for v in self.fleet.vehicles:
            tr = read_track(track_path(self.track_dir, v.sysid))
            snaps = [(s["lat"], s["lon"], s["alt"]) for s in tr.snapshots]
            out[v.sysid] = (tr.t, tr.lat, tr.lon, tr.alt, snaps, tr.home)
        return out

    def stop(self) -> None:
        self.fleet.stop()


class ProcessBackend:
    """Real SITL processes, one per vehicle; judged from the vehicles' own reports."""

    def __init__(self, plan: Plan, workdir: Path, speedup: float):
        self.plan = plan
        self.procs = {}
        self.workdir = workdir
        for i, v in enumerate(plan.vehicles):
            self.procs[i + 1] = self._start(i, v.launch, speedup)

    def kill(self, sysid: int) -> float:
        proc = self.procs[sysid]
        proc.send_signal(signal.SIGKILL)
        t = time.time()
        proc.wait(timeout=10)
        return t

    def stop(self) -> None:
        for proc in self.procs.values():
            if proc.poll() is None:
                proc.terminate()
                try:
                    proc.wait(timeout=10)
                except subprocess.TimeoutExpired:
                    proc.kill()

    def tracks(self, flight_dir: Path) -> dict:
        """Positions and camera feedback the vehicles reported, read from the .tlog files."""
        from gcs.mavlink import mavutil

        out = {}
        for sysid, v in zip(self.procs, self.plan.vehicles):
            path = flight_dir / f"vehicle_{sysid}.tlog"
            log = mavutil.mavlink_connection(str(path))
            t, lat, lon, alt, snaps = [], [], [], [], []
            while True:
                msg = log.recv_match(type=["GLOBAL_POSITION_INT", "CAMERA_FEEDBACK",
                                           "CAMERA_IMAGE_CAPTURED"])
                if msg is None:
                    break
                if msg.get_type() == "GLOBAL_POSITION_INT":
                    t.append(msg._timestamp)
                    lat.append(msg.lat * 1e-7)
                    lon.append(msg.lon * 1e-7)
                    alt.append(msg.alt * 1e-3)
                elif msg.get_type() == "CAMERA_FEEDBACK":
                    snaps.append((msg.lat * 1e-7, msg.lng * 1e-7, msg.alt_msl))
                else:
                    snaps.append((msg.lat * 1e-7, msg.lon * 1e-7, msg.alt * 1e-3))
            home = (v.launch.lat, v.launch.lon, v.launch.alt_amsl)
            out[sysid] = tuple(np.asarray(a, float) for a in (t, lat, lon, alt)) + (snaps, home)
        return out


class ArduPilotBackend(ProcessBackend):
    name = "ardupilot"

    def _start(self, i, launch, speedup):
        cwd = self.workdir / f"ardupilot_{i}"
        cwd.mkdir(parents=True, exist_ok=True)
        cmd = [ARDUPILOT_BIN, "--model", "+", "--speedup", str(speedup), "-I", str(i),
               "--sysid", str(i + 1),
               "--home", f"{launch.lat},{launch.lon},{launch.alt_amsl},0"]
        if os.environ.get("ARDUPILOT_DEFAULTS"):
            cmd[1:1] = ["--defaults", os.environ["ARDUPILOT_DEFAULTS"]]
        return subprocess.Popen(cmd, cwd=cwd, stdout=subprocess.DEVNULL,
                                stderr=subprocess.DEVNULL)

    def urls(self) -> list:
        return [f"tcp:127.0.0.1:{5760 + 10 * i}" for i in range(len(self.procs))]


class Px4Backend(ProcessBackend):
    name = "px4"

    def _start(self, i, launch, speedup):
        binary = Path(PX4_BIN).resolve()
        src = Path(os.environ.get("PX4_SITL_DIR", binary.parents[3]))
        rootfs = src / "build" / "px4_sitl_default" / "rootfs" / str(i)
        shutil.rmtree(rootfs, ignore_errors=True)
        env = dict(os.environ, PX4_SYS_AUTOSTART="10040", PX4_SIM_MODEL="sihsim_quadx",
                   PX4_PARAM_SIH_LOC_LAT0=str(launch.lat), PX4_PARAM_SIH_LOC_LON0=str(launch.lon),
                   PX4_PARAM_SIH_LOC_H0=str(launch.alt_amsl), PX4_SIM_SPEED_FACTOR=str(speedup))
        return subprocess.Popen([str(binary), "-i", str(i), "-d"], cwd=src, env=env,
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                stdin=subprocess.DEVNULL)

    def urls(self) -> list:
        return ["udpin:0.0.0.0:14550"]


class SimPx4Backend(SimBackend):
    """The built-in simulated copters with PX4's modes, start sequence and UDP ports."""

    name = "sim-px4"
    firmware = "px4"


BACKENDS = {"sim": (SimBackend, None), "sim-px4": (SimPx4Backend, None), "ardupilot": (ArduPilotBackend, ARDUPILOT_BIN),
            "px4": (Px4Backend, PX4_BIN)}


@pytest.fixture(params=["sim", "ardupilot", "px4"])
def backend(request):
    """The name of a backend that is available here (real SITL skipped unless named)."""
    name = request.param
    cls, binary = BACKENDS[name]
    if name != "sim" and not binary:
        var = "ARDUPILOT_SITL_BIN" if name == "ardupilot" else "PX4_SITL_BIN"
        pytest.skip(f"real {name} SITL not configured: set {var} to its binary")
    return name


def start_backend(name: str, plan: Plan, workdir: Path, speedup: float | None = None):
    cls, _ = BACKENDS[name]
    return cls(plan, workdir, speedup or SPEEDUP[name])
