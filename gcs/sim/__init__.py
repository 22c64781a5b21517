"""Built-in simulated multicopters that speak MAVLink like ArduPilot or PX4 SITL.

`SimFleet` starts N vehicles on the endpoints real SITL uses (ArduPilot: TCP
5760 + 10*i; PX4: UDP 18570 + i sending to 127.0.0.1:14550), so ground control
code meets the same URLs, message sequences and quirks in tests as in the field.
Each vehicle records its true track (`read_track`) to judge flights independently
of what the ground station believes.
"""

import importlib

#: public name -> the module defining it; loaded on first use, so that importing a
#: light part (the fault syntax, the physics limits) does not start pymavlink
_EXPORTS = {
    "FaultPlan": "faults", "parse_cut": "faults", "parse_kill": "faults",
    "DEFAULT_HOME": "physics", "Limits": "physics",
    "FleetConfig": "fleet", "SimFleet": "fleet", "fleet_for_plan": "fleet",
    "free_base_port": "fleet", "free_fleet_ports": "fleet", "terrain_ground": "fleet",
    "radio_for_plan": "fleet",
    "vehicle_url": "fleet", "vehicle_port": "fleet",
    "Track": "track", "read_track": "track", "track_path": "track",
    "SimVehicle": "vehicle", "VehicleConfig": "vehicle",
}
__all__ = sorted(_EXPORTS)


def __getattr__(name):
    if name not in _EXPORTS:
        raise AttributeError(f"module 'gcs.sim' has no attribute {name!r}")
    return getattr(importlib.import_module(f"gcs.sim.{_EXPORTS[name]}"), name)
