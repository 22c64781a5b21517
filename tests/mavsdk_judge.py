"""MAVSDK as an outside reader of the mission files: its QGroundControl and Mission
Planner importers, for the tests of more than one module (a module of its own:
test modules cannot import from conftest, which sitl_tests has one of too): each
test module makes its fixture of `mission_raw`."""

import contextlib
import socket


def _free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@contextlib.contextmanager
def mission_raw():
    """MissionRaw of a ground-station MAVSDK connected, over loopback UDP, to an
    autopilot-side MAVSDK with a MissionRawServer (MAVSDK 4 needs a system)."""
    from mavsdk import ComponentType, Configuration, Mavsdk
    from mavsdk.plugins.mission_raw import MissionRaw
    from mavsdk.plugins.mission_raw_server import MissionRawServer

    port = _free_udp_port()
    autopilot = Mavsdk(Configuration.create_with_component_type(ComponentType.AUTOPILOT))
    ground = Mavsdk(Configuration.create_with_component_type(ComponentType.GROUND_STATION))
    try:
        ground.add_any_connection(f"udpin://127.0.0.1:{port}")
        autopilot.add_any_connection(f"udpout://127.0.0.1:{port}")
        server = MissionRawServer(autopilot.server_component())
        system = ground.first_autopilot(10.0)
        assert system is not None, "MAVSDK ground station found no autopilot"
        yield MissionRaw(system)
        del server
    finally:
        ground.destroy()
        autopilot.destroy()
