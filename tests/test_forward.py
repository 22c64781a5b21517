"""`gcs fly --forward URL` (issue 23): a third-party MAVLink client (plain
pymavlink, standing in for QGroundControl) on the forwarded port sees every
vehicle of a simulated flight, its positions and its mission progress; what it
sends back is dropped unless --forward-commands. The plan is tests/conftest.py's."""

import json
import socket
import threading
import time
from collections import defaultdict

import pytest
from flown import problems_beside_guard
from sim_fleet import quick_fleet

from common.errors import InputError
from common.geo import distance_m
from gcs.cli import main
from gcs.forward import Forwarder
from gcs.link import GroundLink
from gcs.mavlink import GCS_SYSTEM_ID, M, mavutil
from gcs.sim import free_base_port

pytestmark = pytest.mark.timeout(180)

STATION = 250          # the forwarded station's system id (QGroundControl's is 255)


def _free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Station:
    """A pymavlink ground station listening where gcs forwards to; it records what
    it hears and, when asked, sends commands back every half second."""

    def __init__(self, port, nuisance=False):
        self.conn = mavutil.mavlink_connection(f"udpin:127.0.0.1:{port}",
                                               source_system=STATION, source_component=190)
        self.heartbeats = defaultdict(int)
        self.positions = defaultdict(list)
        self.current = defaultdict(set)
        self.reached = defaultdict(set)
        self.acks = []
        self.to_gcs = []
        self.nuisance = nuisance
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self):
        last = 0.0
        while not self._stop.is_set():
            msg = self.conn.recv_match(blocking=True, timeout=0.1)
            if self.nuisance and time.monotonic() - last > 0.5 and self.heartbeats:
                last = time.monotonic()
                for sysid in list(self.heartbeats):       # a second station, fighting
                    self.conn.mav.command_long_send(
                        sysid, 1, M.MAV_CMD_COMPONENT_ARM_DISARM, 0, 0, 21196, 0, 0, 0, 0, 0)
                    self.conn.mav.set_mode_send(sysid, M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 6)
            if msg is None:
                continue
            kind, sysid = msg.get_type(), msg.get_srcSystem()
            if getattr(msg, "target_system", 0) == GCS_SYSTEM_ID:
                self.to_gcs.append(kind)
            if kind == "HEARTBEAT" and msg.autopilot != M.MAV_AUTOPILOT_INVALID:
                self.heartbeats[sysid] += 1
            elif kind == "GLOBAL_POSITION_INT":
                self.positions[sysid].append((msg.lat * 1e-7, msg.lon * 1e-7, msg.alt * 1e-3))
            elif kind == "MISSION_CURRENT":
                self.current[sysid].add(msg.seq)
            elif kind == "MISSION_ITEM_REACHED":
                self.reached[sysid].add(msg.seq)
            elif kind == "COMMAND_ACK":
                self.acks.append((sysid, msg.command, msg.result, msg.target_system))

    def close(self):
        self._stop.set()
        self._thread.join(timeout=2)
        self.conn.close()


def test_qgroundcontrol_sees_the_fleet_and_cannot_command_it(plan_dir, tmp_path):
    port = _free_udp_port()
    station = Station(port, nuisance=True)
    out = tmp_path / "flight"
    try:
        code = main(["fly", str(plan_dir), "--sim", "3", "--speedup", "100",
                     "--sim-base-port", str(free_base_port(10, 3)),
                     "--forward", f"udpout:127.0.0.1:{port}", "-o", str(out)])
    finally:
        station.close()
    report = json.loads((out / "flight.json").read_text())
    # the station's disarms and mode changes were dropped: the flight went as planned
    assert problems_beside_guard(report) == [], report["outcome"]
    assert code == (0 if report["outcome"]["ok"] else 1)
    assert {v["state"] for v in report["vehicles"]} == {"landed"}
    assert not station.acks                  # nothing it sent reached a vehicle
    # every system id, live positions along the flight and mission progress
    assert sorted(station.heartbeats) == [1, 2, 3]
    for v in report["vehicles"]:
        seen = station.positions[v["sysid"]]
        assert len(seen) >= 20, v["sysid"]
        flown = v["track"]
        # the forwarded positions are the vehicle's own: they end where it landed
        assert distance_m(seen[-1][0], seen[-1][1], flown[-1][2], flown[-1][1]) < 5.0
        top = max(p[2] for p in seen)
        assert top - seen[0][2] > 20.0                    # it saw the climb
        assert len(station.reached[v["sysid"]]) >= 5      # mission progress
        assert max(station.current[v["sysid"]]) >= 5
    # answers meant for gcs (mission protocol, acks) stay with gcs
    assert not station.to_gcs


@pytest.fixture
def fleet():
    f = quick_fleet(2, warmup_s=1.0, no_space_s=1.0, speedup=10.0)
    yield f
    f.stop()


def _ask_version(station, sysid, timeout=3.0):
    """MAV_CMD_REQUEST_MESSAGE from the station; the COMMAND_ACK addressed to it."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        station.conn.mav.command_long_send(sysid, 1, M.MAV_CMD_REQUEST_MESSAGE, 0,
                                           M.MAVLINK_MSG_ID_AUTOPILOT_VERSION, 0, 0, 0, 0, 0, 0)
        end = time.monotonic() + 0.3
        while time.monotonic() < end:
            acks = [a for a in station.acks if a[0] == sysid and a[1] == M.MAV_CMD_REQUEST_MESSAGE]
            if acks:
                return acks[0]
            time.sleep(0.02)
    return None


@pytest.mark.parametrize("commands", [False, True])
def test_the_way_back_opens_only_with_forward_commands(fleet, commands):
    port = _free_udp_port()
    station = Station(port)
    forward = Forwarder([f"udpout:127.0.0.1:{port}"], forward_commands=commands)
    try:
        with GroundLink.open(fleet.urls(), expect=2, timeout_s=10, forward=forward):
            deadline = time.monotonic() + 5
            while sorted(station.heartbeats) != [1, 2] and time.monotonic() < deadline:
                time.sleep(0.05)
            assert sorted(station.heartbeats) == [1, 2]
            ack = _ask_version(station, 2)
            if commands:
                assert ack is not None and ack[3] == STATION     # answered to the station
                assert forward.passed["COMMAND_LONG"] >= 1
            else:
                assert ack is None and forward.dropped["COMMAND_LONG"] >= 1
                assert "--forward-commands passes them" in forward.summary()
    finally:
        station.close()
        forward.close()


def test_bad_forward_url_is_bad_input(plan_dir, tmp_path, capsys):
    out = tmp_path / "flight"
    assert main(["fly", str(plan_dir), "--sim", "3", "--forward", "127.0.0.1:14550",
                 "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("gcs fly: error: --forward: 127.0.0.1:14550: not a connection URL")
    assert len(err.splitlines()) == 1 and not out.exists()
    assert main(["fly", str(plan_dir), "--sim", "3", "--forward-commands",
                 "-o", str(out)]) == 2
    assert "give --forward URL too" in capsys.readouterr().err
    with pytest.raises(InputError):
        from gcs.cli.fly import forwarder
        forwarder(type("A", (), {"forward": ["tcp:127.0.0.1:1"], "forward_commands": False})())


def test_a_command_passed_on_is_counted_before_it_reaches_the_vehicle():
    """The vehicle's answer comes back on another thread: a count made after the write
    once still said no COMMAND_LONG was passed when the station had its answer."""
    from types import SimpleNamespace

    forward = Forwarder([f"udpout:127.0.0.1:{_free_udp_port()}"], forward_commands=True)
    counted = []
    route = (object(), None)
    forward._ground = SimpleNamespace(
        vehicles={2: SimpleNamespace(connection=route[0], _route=route)},
        _write_raw=lambda conn, packet, addr: counted.append(forward.passed["COMMAND_LONG"]))
    mav = mavutil.mavlink.MAVLink(None, srcSystem=STATION, srcComponent=190)
    msg = mav.command_long_encode(2, 1, M.MAV_CMD_REQUEST_MESSAGE, 0, 148, 0, 0, 0, 0, 0, 0)
    msg.pack(mav)
    try:
        forward._incoming(msg)
    finally:
        forward.close()
    assert counted == [1]
