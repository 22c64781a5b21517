"""Built-in simulated multicopters that speak MAVLink like ArduPilot or PX4 SITL.

`SimFleet` starts N vehicles on the endpoints real SITL uses (ArduPilot: TCP
5760 + 10*i; PX4: UDP 18570 + i sending to 127.0.0.1:14550), so ground control
code meets the same URLs, message sequences and quirks in tests as in the field.
Each vehicle records its true track (`read_track`) to judge flights independently
of what the ground station believes.
"""

from gcs.sim.faults import FaultPlan, parse_cut, parse_kill
from gcs.sim.fleet import (FleetConfig, SimFleet, fleet_for_plan, free_base_port,
                           free_fleet_ports, terrain_ground, vehicle_url)
from gcs.sim.physics import Limits
from gcs.sim.track import Track, read_track, track_path
from gcs.sim.vehicle import SimVehicle, VehicleConfig

__all__ = ["FaultPlan", "FleetConfig", "Limits", "SimFleet", "SimVehicle", "Track",
           "VehicleConfig", "fleet_for_plan", "free_base_port", "free_fleet_ports", "parse_cut",
           "parse_kill", "read_track", "terrain_ground", "track_path", "vehicle_url"]
