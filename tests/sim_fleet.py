"""The simulated fleets the tests fly, set up in one place: booted and ready at
once, on free local ports, at the speed-up of the tests' short flights."""

from gcs.sim import FleetConfig, SimFleet, free_fleet_ports

#: ready to arm half a wall second after boot, taking uploads at once (each
#: firmware's own boot, sped up, would take seconds of the suite per fleet)
QUICK = {"warmup_s": 0.5, "no_space_s": 0.0}
#: the tests' short flights: quick, and slow enough for the separation guard's loop
SPEEDUP = 20.0


def quick_config(vehicles=1, firmware="ardupilot", **config) -> FleetConfig:
    """`FleetConfig` of ``vehicles`` simulated ``firmware`` autopilots, `QUICK` to
    start, at `SPEEDUP`, on free local ports unless ``config`` (FleetConfig's
    fields) says otherwise."""
    ports = {} if "base_port" in config or config.get("transport") == "pty" else \
        free_fleet_ports(firmware, vehicles)
    return FleetConfig(vehicles=vehicles, firmware=firmware,
                       **{**QUICK, "speedup": SPEEDUP, **ports, **config})


def quick_fleet(vehicles=1, firmware="ardupilot", **config) -> SimFleet:
    """`quick_config`'s fleet, started."""
    return SimFleet(quick_config(vehicles, firmware, **config)).start()
