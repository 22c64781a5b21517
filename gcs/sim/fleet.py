"""A fleet of simulated vehicles in one process, one thread each.

    fleet = SimFleet(FleetConfig(vehicles=3, firmware="ardupilot", speedup=10,
                                 base_port=15760, track_dir="tracks")).start()
    fleet.urls()          # ['tcp:127.0.0.1:15760', 'tcp:127.0.0.1:15770', ...]
    fleet.kill(2)         # system id 2 stops talking, its socket closes
    fleet.stop()

Vehicles are addressed by MAVLink system id (1..N), as a ground station sees them.
"""

import random
import socket
import threading
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

from autopilots import ARDUPILOT, firmware_of
from gcs.sim.faults import FaultPlan
from gcs.sim.flavours import flavour
from gcs.sim.lockstep import Lockstep
from gcs.sim.physics import DEFAULT_HOME, PLANNED_RATES, Limits
from gcs.sim.track import track_path
from gcs.sim.vehicle import FIRMWARE_CAPACITY, SimVehicle, VehicleConfig


def vehicle_port(firmware: str, index: int, base_port: int | None = None) -> int:
    f = flavour(firmware)
    base = f.base_port if base_port is None else base_port
    return base + f.port_step * index


def vehicle_url(firmware: str, index: int, base_port: int | None = None,
                gcs_port: int = 14550) -> str:
    """The pymavlink URL a ground station uses for vehicle `index` (0-based)."""
    if flavour(firmware).transport == "tcp":
        return f"tcp:127.0.0.1:{vehicle_port(firmware, index, base_port)}"
    return f"udpin:0.0.0.0:{gcs_port}"      # every UDP instance sends to the same port


@dataclass
class FleetConfig:
    vehicles: int = 1
    firmware: str = ARDUPILOT                   # an autopilots profile name
    home: tuple = DEFAULT_HOME                  # lat, lon, ground alt AMSL, for every vehicle
    homes: list | None = None                   # or one (lat, lon, alt) per vehicle
    speedup: float = 1.0
    base_port: int | None = None                # default: 5760 (ArduPilot) / 18570 (PX4)
    gcs_port: int = 14550                       # PX4: where telemetry is sent
    bind_host: str = "127.0.0.1"
    limits: Limits = field(default_factory=Limits)
    warmup_s: float | None = None               # None: the firmware's boot times / speedup
    no_space_s: float = 1.0
    auto_disarm_s: float = 10.0
    camera: bool = True
    auto_options: int = 0
    drop_pct: float = 0.0
    faults: dict = field(default_factory=dict)  # system id -> FaultPlan
    track_dir: Path | str | None = None
    seed: int = 0
    signing_key: bytes | None = None
    terrain: object = None                      # (lat, lon) -> ground m AMSL; None: flat
                                                # at each home's altitude, as SITL
    radio: object = None                        # (lat, lon, alt) -> heard: the radio's
                                                # shadows (planner.link.contact_at)
    transport: str | None = None                # "pty": each vehicle on a serial line
    serial_baud: int = 57600                    # what urls() asks a pty link for
    mission_capacity: int | None | str = FIRMWARE_CAPACITY   # items held; None: no limit
    battery_min: float = 60.0                   # flight time of a full battery
    swap_s: float = 60.0                        # on the ground, disarmed, until it is swapped
    swap_reboot_s: float = 0.0                  # wall s each swap powers the autopilot down

    def vehicle_configs(self) -> list:
        flavour(self.firmware)                  # ValueError naming the choices
        if self.homes is not None and len(self.homes) != self.vehicles:
            raise ValueError(f"{len(self.homes)} homes given for {self.vehicles} vehicles")
        unknown = set(self.faults) - set(range(1, self.vehicles + 1))
        if unknown:
            raise ValueError(f"faults for unknown system ids {sorted(unknown)}")
        configs = []
        for i in range(self.vehicles):
            sysid = i + 1
            home = tuple(self.homes[i]) if self.homes is not None else tuple(self.home)
            configs.append(VehicleConfig(
                sysid=sysid, port=vehicle_port(self.firmware, i, self.base_port),
                firmware=self.firmware, home=home,
                gcs_address=("127.0.0.1", self.gcs_port), bind_host=self.bind_host,
                speedup=self.speedup, limits=self.limits, warmup_s=self.warmup_s,
                no_space_s=self.no_space_s, auto_disarm_s=self.auto_disarm_s,
                camera=self.camera, auto_options=self.auto_options, drop_pct=self.drop_pct,
                faults=replace(self.faults.get(sysid, FaultPlan())),
                track_path=track_path(self.track_dir, sysid) if self.track_dir else None,
                seed=self.seed, signing_key=self.signing_key, terrain=self.terrain,
                radio=self.radio,
                transport=self.transport, mission_capacity=self.mission_capacity,
                battery_min=self.battery_min, swap_s=self.swap_s,
                swap_reboot_s=self.swap_reboot_s))
        return configs


#: wall seconds `SimFleet.kill` waits for the vehicle's own loop to go silent (at once
#: on an idle machine; generous for a loaded one)
KILL_WAIT_S = 30.0


class SimFleet:
    def __init__(self, config: FleetConfig):
        self.config = config
        self.lockstep = Lockstep()
        self.vehicles = [SimVehicle(c, self.lockstep) for c in config.vehicle_configs()]
        self._threads = []

    def start(self) -> "SimFleet":
        """Bind every endpoint (OSError if one is taken: nothing is left open), then run."""
        opened = []
        try:
            for v in self.vehicles:
                v.open()
                opened.append(v)
        except OSError:
            for v in opened:
                v.link.close()
            raise
        for v in self.vehicles:
            thread = threading.Thread(target=v.run, name=f"sim-vehicle-{v.sysid}", daemon=True)
            thread.start()
            self._threads.append(thread)
        return self

    def stop(self) -> None:
        for v in self.vehicles:
            v.stop()
        for thread in self._threads:
            thread.join(timeout=5)
        self._threads = []

    def __enter__(self) -> "SimFleet":
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()

    def vehicle(self, sysid: int) -> SimVehicle:
        if not 1 <= sysid <= len(self.vehicles):
            raise ValueError(f"no simulated vehicle with system id {sysid}")
        return self.vehicles[sysid - 1]

    def urls(self) -> list:
        """Ground-station URLs: one per vehicle (TCP: ArduPilot), one shared port (UDP: PX4)."""
        c = self.config
        if c.transport == "pty":
            return [f"{v.link.device},{c.serial_baud}" for v in self.vehicles]
        if flavour(c.firmware).transport == "udp":
            return [vehicle_url(c.firmware, 0, c.base_port, c.gcs_port)]
        return [vehicle_url(c.firmware, i, c.base_port) for i in range(c.vehicles)]

    def kill(self, sysid: int) -> None:
        """Shoot vehicle `sysid` down now: no more output, its sockets closed."""
        v = self.vehicle(sysid)
        v.request_kill()
        if self._threads and not v.dead:
            self.wait_removed(sysid, KILL_WAIT_S)

    def cut_link(self, sysid: int, seconds: float) -> None:
        """Nothing in or out for `seconds` of wall time; the vehicle flies on."""
        self.vehicle(sysid).link_faults.cut(time.monotonic(), seconds)

    def set_drop(self, pct: float, sysid: int | None = None) -> None:
        """Drop `pct` % of packets in both directions (all vehicles, or one)."""
        for v in self.vehicles if sysid is None else [self.vehicle(sysid)]:
            v.link_faults.drop_pct = float(pct)

    def refuse_arm(self, sysid: int, refuse: bool = True) -> None:
        self.vehicle(sysid).plan.refuse_arm = refuse

    def alive(self) -> list:
        """System ids of the vehicles still running."""
        return [v.sysid for v in self.vehicles if not v.dead]

    def wait_removed(self, sysid: int, timeout_s: float = 60.0) -> float:
        """Wait until vehicle ``sysid`` has been shot down (by a fault plan or
        `kill`); its mission time (s) then. TimeoutError after ``timeout_s`` wall
        seconds: the fleet's clock is one a busy machine slows, so a caller waits
        on this event, not on a wall-clock guess."""
        v = self.vehicle(sysid)
        if not v.removed.wait(timeout_s):
            raise TimeoutError(f"simulated vehicle {sysid} was not removed within "
                               f"{timeout_s:g} s (mission time {v.t:.1f} s)")
        return v.track.killed_at

    def wait_mission_time(self, sysid: int, t_s: float, timeout_s: float = 60.0) -> None:
        """Wait until vehicle ``sysid``'s mission clock reaches ``t_s`` (or it is
        removed); TimeoutError after ``timeout_s`` wall seconds."""
        v = self.vehicle(sysid)
        end = time.monotonic() + timeout_s
        while v.t < t_s and not v.dead:
            if time.monotonic() > end:
                raise TimeoutError(f"simulated vehicle {sysid}: mission time {v.t:.1f} s, "
                                   f"not {t_s:g} s, after {timeout_s:g} s")
            time.sleep(0.01)


def fleet_for_plan(plan, vehicles: int | None = None, **config) -> SimFleet:
    """A started fleet for a dry run of ``plan``: one vehicle per route (or
    ``vehicles``), each at its route's launch point, its autopilot set to the plan's
    rates (as an operator sets WPNAV_SPEED_UP / _DN or MPC_Z_V_AUTO_UP / _DN, and
    `gcs fly` checks) unless ``config`` gives ``limits``; ``config`` as FleetConfig.

    OSError if an endpoint is taken (nothing is left open)."""
    n = len(plan.vehicles) if vehicles is None else vehicles
    homes = []
    for i in range(n):
        route = plan.vehicles[i % len(plan.vehicles)]
        if route.launch is None:
            raise ValueError(f"plan vehicle {route.id} has no launch point to start from")
        homes.append((route.launch.lat, route.launch.lon, route.launch.alt_amsl))
    config.setdefault("firmware", firmware_of(plan.params))
    config.setdefault("limits", Limits(**{name: plan.params[name] for name in PLANNED_RATES
                                          if plan.params.get(name) is not None}))
    return SimFleet(FleetConfig(vehicles=n, homes=homes, **config)).start()


def radio_for_plan(plan, terrain):
    """FleetConfig.radio for a plan: its antennas and radio (plan.json metrics.link)
    on ``terrain``; None when the plan predicts no link (no antenna)."""
    from planner.link import Antenna, Radio, contact_at

    link = (plan.metrics or {}).get("link")
    if not link:
        return None
    r = link["radio"]
    return contact_at(terrain, [Antenna(*a) for a in link["antennas"]],
                      Radio(r["mhz"], r["range_m"], r["fresnel"], r.get("near_m", 100.0)))


def terrain_ground(terrain):
    """(lat, lon) -> ground m AMSL on a `planner.terrain.Terrain`, for FleetConfig.terrain:
    simulated vehicles then touch down (or crash) on the real relief. The ground is
    the plan's ground for clearance (its upper surface, nowhere below the DEM), the
    one its bases stand on: a vehicle lands where it took off."""
    def ground(lat: float, lon: float) -> float:
        return terrain.ground_at(*terrain.from_lonlat(lon, lat), upper=True)
    return ground


def free_base_port(step: int = 10, count: int = 1, udp: bool = False) -> int:
    """A first port P with P + step*i free on 127.0.0.1 for i < count (tests and
    dry runs that must not meet a real SITL on its default ports)."""
    kind = socket.SOCK_DGRAM if udp else socket.SOCK_STREAM
    rng = random.Random()
    for _ in range(500):
        base = rng.randrange(20000, 60000 - step * count)
        if all(_bindable(base + step * i, kind) for i in range(count)):
            return base
    raise OSError("no free range of local ports")


def free_fleet_ports(firmware: str, vehicles: int) -> dict:
    """FleetConfig port fields for ``vehicles`` of ``firmware`` on free local ports:
    ArduPilot TCP P + 10*i; PX4 UDP P + 1 + i, all sending to UDP P."""
    f = flavour(firmware)
    if f.transport == "tcp":
        return {"base_port": free_base_port(f.port_step, vehicles)}
    first = free_base_port(1, vehicles + 1, udp=True)
    return {"gcs_port": first, "base_port": first + 1}


def _bindable(port: int, kind) -> bool:
    with socket.socket(socket.AF_INET, kind) as s:
        try:
            s.bind(("127.0.0.1", port))
        except OSError:
            return False
    return True
