"""Links: vehicles found by HEARTBEAT, per-vehicle routing on a shared UDP port,
signing, .tlog recording. References: the simulated vehicles, plain pymavlink
endpoints standing in for other ground stations and cameras, pymavlink's tlog
reader, hashlib for MAVProxy's passphrase rule."""

import hashlib
import socket
import threading
import time

import pytest
from sim_fleet import quick_config

from common.errors import InputError
from gcs import commands, signing
from gcs.link import GroundLink, LinkError, build_message
from gcs.mavlink import M, mavutil, mode_name, mode_number
from gcs.sim import FleetConfig, SimFleet, free_base_port

pytestmark = pytest.mark.timeout(60)

# the links meet the autopilots' first second after boot, refusing uploads
BOOTING = dict(warmup_s=1.0, no_space_s=1.0, speedup=10.0)


def fleet_config(firmware, vehicles, **kw) -> FleetConfig:
    return quick_config(vehicles, firmware, **{**BOOTING, **kw})


@pytest.fixture
def fleet_of():
    fleets = []

    def start(cfg):
        fleets.append(SimFleet(cfg).start())
        return fleets[-1]

    yield start
    for f in fleets:
        f.stop()


def wait_until(predicate, timeout=5.0):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.05)
    return False


# -- finding vehicles ------------------------------------------------------------------
def test_a_lost_stream_request_is_sent_again(fleet_of, monkeypatch):
    """ArduPilot streams nothing until asked; when that request is lost (a radio
    drops packets) the ground station asks again on a later HEARTBEAT."""
    from gcs.link import VehicleLink

    asked = []
    real = VehicleLink.request_streams

    def first_one_lost(self, *a, **kw):
        asked.append(time.monotonic())
        if len(asked) == 1:
            self._asked_at = time.monotonic()    # sent, and lost on the way
            return
        real(self, *a, **kw)

    monkeypatch.setattr(VehicleLink, "request_streams", first_one_lost)
    fleet = fleet_of(fleet_config("ardupilot", 1))
    with GroundLink.open(fleet.urls(), expect=1, timeout_s=10) as link:
        v = link.vehicles[1]
        assert wait_until(lambda: v.state.lat is not None, timeout=10.0)
        assert len(asked) >= 2


@pytest.mark.parametrize("firmware", ["ardupilot", "px4"])
def test_vehicles_found_by_heartbeat(fleet_of, firmware):
    fleet = fleet_of(fleet_config(firmware, 3))
    with GroundLink.open(fleet.urls(), expect=3, timeout_s=10) as link:
        assert sorted(link.vehicles) == [1, 2, 3]
        # found by a HEARTBEAT, so never "silent since forever" (a monitor would
        # declare such a vehicle lost at once)
        assert all(v.heartbeat_age() < 2.0 for v in link.vehicles.values())
        for sysid, v in link.vehicles.items():
            assert (v.sysid, v.compid, v.flavour) == (sysid, 1, firmware)
            assert wait_until(lambda: v.state.ready and v.state.lat is not None)
            assert v.state.lat == pytest.approx(-35.363261, abs=1e-6)
            assert v.state.alt_amsl == pytest.approx(584.0, abs=0.01)
            assert v.state.mode == ("STABILIZE" if firmware == "ardupilot" else "AUTO.LOITER")
            assert v.state.landed is True and v.state.armed is False
            assert v.heartbeat_age() < 2.0


def test_open_without_expect_waits_for_every_vehicle_on_a_shared_port(fleet_of):
    fleet = fleet_of(fleet_config("px4", 3))
    with GroundLink.open(fleet.urls(), timeout_s=10) as link:
        assert sorted(link.vehicles) == [1, 2, 3]


def test_udpout_reaches_a_vehicle_that_waits_to_be_spoken_to(fleet_of):
    # The PX4 flavour answers whoever spoke last: our GCS HEARTBEAT opens the way.
    cfg = fleet_config("px4", 1)
    fleet_of(cfg)  # started, stopped by the fixture
    with GroundLink.open([f"udpout:127.0.0.1:{cfg.base_port}"], expect=1, timeout_s=10) as link:
        v = link.vehicles[1]
        v.send("MISSION_REQUEST_LIST", mission_type=0)
        assert v.recv("MISSION_COUNT", 3.0) is not None


def test_serial_urls_carry_their_baud():
    from gcs.link import _split_serial
    assert _split_serial("/dev/ttyACM0,57600") == ("/dev/ttyACM0", 57600)
    assert _split_serial("/dev/ttyUSB0") == ("/dev/ttyUSB0", 115200)
    assert _split_serial("tcp:127.0.0.1:5760") == ("tcp:127.0.0.1:5760", 115200)


def test_open_names_what_is_missing(fleet_of):
    fleet = fleet_of(fleet_config("ardupilot", 1))
    with pytest.raises(LinkError, match=r"2 vehicle\(s\), found 1 \[1\] within 1 s"):
        GroundLink.open(fleet.urls(), expect=2, timeout_s=1)
    port = free_base_port(1, 1, udp=True)
    with pytest.raises(LinkError, match="nothing received at all"):
        GroundLink.open([f"udpin:127.0.0.1:{port}"], expect=1, timeout_s=0.5)
    with socket.socket() as held:       # bound, not listening: refused, and no test
        held.bind(("127.0.0.1", 0))     # running beside this one can take the port
        with pytest.raises(LinkError, match="cannot open"):
            GroundLink.open([f"tcp:127.0.0.1:{held.getsockname()[1]}"], timeout_s=0.5)


class _Rebooting:
    """An autopilot on a TCP port, as SITL serves one, sending HEARTBEATs; `reboot`
    closes its port for a while (a battery swap powering it down), then serves it
    again. Counts the clients that connected."""

    def __init__(self):
        self.mav = M.MAVLink(None, srcSystem=7, srcComponent=1)
        self.clients, self.port, self.up = 0, None, True
        self._stop = threading.Event()
        self._listener = self._listen()
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    def _listen(self, port=0):
        s = socket.socket()
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        s.bind(("127.0.0.1", port))
        s.listen(1)
        s.settimeout(0.1)
        self.port = s.getsockname()[1]
        return s

    def _serve(self):
        client = None
        while not self._stop.is_set():
            if not self.up:
                if client is not None:
                    client.close()
                    client = None
                time.sleep(0.05)
                continue
            if client is None:
                try:
                    client, _ = self._listener.accept()
                    self.clients += 1
                except OSError:
                    continue
            beat = self.mav.heartbeat_encode(M.MAV_TYPE_QUADROTOR, M.MAV_AUTOPILOT_ARDUPILOTMEGA,
                                             0, 0, M.MAV_STATE_STANDBY)
            try:
                client.sendall(beat.pack(self.mav))
            except OSError:
                client = None
            time.sleep(0.2)

    def reboot(self, seconds):
        self.up = False
        time.sleep(0.2)
        self._listener.close()
        time.sleep(seconds)
        self._listener = self._listen(self.port)
        self.up = True

    def stop(self):
        self._stop.set()
        self._thread.join(2)
        self._listener.close()


def test_a_tcp_autopilot_that_reboots_is_connected_to_again():
    """An autopilot rebooting (a battery swap) closes its TCP port: the link
    connects again once it serves it, and hears it; closed by us, never again."""
    vehicle = _Rebooting()
    try:
        with GroundLink.open([f"tcp:127.0.0.1:{vehicle.port}"], expect=1, timeout_s=5) as link:
            v, conn = link.vehicles[7], link.connections[0]
            vehicle.reboot(2.5)
            assert wait_until(lambda: conn.reconnects >= 1 and v.heartbeat_age() < 0.5)
            assert vehicle.clients == 2
        time.sleep(2.5)                    # RECONNECT_S and more: nobody came back
        assert vehicle.clients == 2 and conn.shut
    finally:
        vehicle.stop()


def test_ground_stations_and_cameras_are_not_vehicles(fleet_of):
    fleet = fleet_of(fleet_config("px4", 1))
    port = fleet.config.gcs_port
    others = []
    for sysid, compid, mav_type, autopilot in [(200, 190, M.MAV_TYPE_GCS, M.MAV_AUTOPILOT_INVALID),
                                              (1, 100, M.MAV_TYPE_CAMERA, M.MAV_AUTOPILOT_INVALID),
                                              (7, 191, M.MAV_TYPE_ONBOARD_CONTROLLER,
                                               M.MAV_AUTOPILOT_GENERIC)]:
        c = mavutil.mavlink_connection(f"udpout:127.0.0.1:{port}", source_system=sysid,
                                       source_component=compid)
        others.append((c, mav_type, autopilot))
    with GroundLink.open(fleet.urls(), expect=1, timeout_s=10) as link:
        for _ in range(3):
            for c, mav_type, autopilot in others:
                c.mav.heartbeat_send(mav_type, autopilot, 0, 0, 0)
            time.sleep(0.3)
        assert list(link.vehicles) == [1]
        assert link.vehicles[1].compid == 1           # the camera of system 1 is not it
    for c, _, _ in others:
        c.close()


# -- routing on a shared UDP port ----------------------------------------------------------
def test_px4_instances_on_one_port_each_get_their_own_messages(fleet_of):
    fleet = fleet_of(fleet_config("px4", 3))
    with GroundLink.open(fleet.urls(), expect=3, timeout_s=10) as link:
        vehicles = link.vehicles
        addresses = {v.sysid: v._route[1] for v in vehicles.values()}
        assert len(set(addresses.values())) == 3      # three source ports
        # Ask in reverse order: pymavlink's udpin would answer whoever spoke last.
        for sysid in (3, 1, 2):
            vehicles[sysid].send("PARAM_REQUEST_READ", param_id=b"SYSID_THISMAV",
                                 param_index=-1)
        for sysid, v in vehicles.items():
            answer = v.recv("PARAM_VALUE", 3.0)
            assert answer is not None and answer.param_value == sysid
        # a mode change addressed to vehicle 2 changes vehicle 2 only
        commands.wait_ready(vehicles[2], 10)
        commands.set_mode(vehicles[2], "POSCTL")
        assert [v.mode for v in fleet.vehicles] == ["AUTO.LOITER", "POSCTL", "AUTO.LOITER"]


def test_recv_subscribe_flush(fleet_of):
    fleet = fleet_of(fleet_config("ardupilot", 1))
    with GroundLink.open(fleet.urls(), expect=1, timeout_s=10) as link:
        v = link.vehicles[1]
        seen = []
        unsubscribe = v.subscribe(lambda msg: seen.append(msg.get_type()))
        assert v.recv("GLOBAL_POSITION_INT", 2.0) is not None
        first = v.recv(["HEARTBEAT", "SYS_STATUS"], 3.0, lambda m: m.get_type() == "SYS_STATUS")
        assert first.get_type() == "SYS_STATUS"
        assert v.recv("NO_SUCH_MESSAGE", 0.1) is None
        v.flush()
        assert v.recv("HEARTBEAT", 0.0) is None
        assert wait_until(lambda: {"HEARTBEAT", "GLOBAL_POSITION_INT"} <= set(seen))
        unsubscribe()
        count = len(seen)
        time.sleep(0.5)
        assert len(seen) == count


def test_build_message_fills_unset_fields():
    msg = build_message("MISSION_COUNT", {"target_system": 3, "count": 7})
    assert (msg.target_system, msg.target_component, msg.count, msg.mission_type) == (3, 0, 7, 0)
    with pytest.raises(ValueError, match="unknown MAVLink message"):
        build_message("NOT_A_MESSAGE", {})
    with pytest.raises(ValueError, match="unknown fields"):
        build_message("MISSION_COUNT", {"cuont": 1})


def test_mode_names_round_trip():
    for flavour, names in [("ardupilot", ["STABILIZE", "GUIDED", "AUTO", "RTL", "LAND"]),
                           ("px4", ["POSCTL", "AUTO.MISSION", "AUTO.LOITER", "AUTO.RTL"])]:
        for name in names:
            custom = mode_number(flavour, name)[0]
            assert mode_name(flavour, custom) == name
    with pytest.raises(KeyError, match="unknown PX4 mode"):
        mode_number("px4", "GUIDED")


# -- signing ---------------------------------------------------------------------------------
def test_load_key(tmp_path):
    raw = bytes(range(32))
    (tmp_path / "raw.key").write_bytes(raw)
    assert signing.load_key(tmp_path / "raw.key") == raw
    (tmp_path / "phrase.txt").write_text("correct horse battery staple\n")
    assert signing.load_key(tmp_path / "phrase.txt") == \
        hashlib.sha256(b"correct horse battery staple").digest()       # MAVProxy's rule
    (tmp_path / "empty").write_text("  \n")
    with pytest.raises(InputError, match="empty"):
        signing.load_key(tmp_path / "empty")
    with pytest.raises(InputError, match="cannot read"):
        signing.load_key(tmp_path / "missing")


@pytest.mark.parametrize("firmware", ["ardupilot", "px4"])
def test_signed_fleet(fleet_of, firmware):
    key = signing.key_from_passphrase("hidden coverage")
    fleet = fleet_of(fleet_config(firmware, 2, signing_key=key))
    urls = fleet.urls()
    # the right key: found, and the vehicle answers our signed requests
    with GroundLink.open(urls, signing_key=key, expect=2, timeout_s=10) as link:
        for v in link.vehicles.values():
            v.send("MISSION_REQUEST_LIST", mission_type=0)
            assert v.recv("MISSION_COUNT", 3.0) is not None
    # a wrong key: nothing accepted, and the error says why
    with pytest.raises(LinkError, match="rejected for their signature.*key differs"):
        GroundLink.open(urls, signing_key=signing.key_from_passphrase("wrong"), expect=2,
                        timeout_s=2)
    # no key: the vehicles ignore us, and a command's timeout says so
    with GroundLink.open(urls, expect=2, timeout_s=10) as link:
        v = link.vehicles[1]
        assert v.signs
        with pytest.raises(commands.CommandError, match="no COMMAND_ACK"):
            commands.command_long(v, M.MAV_CMD_REQUEST_MESSAGE, M.MAVLINK_MSG_ID_AUTOPILOT_VERSION,
                                  timeout_s=0.2, retries=1)
        from gcs import mission_protocol as mp
        with pytest.raises(mp.MissionError, match="signs its messages.*--signing-key"):
            mp.clear(v, timeout_s=0.2, retries=1)


def test_unsigned_messages_are_dropped_when_we_have_a_key(fleet_of):
    fleet = fleet_of(fleet_config("px4", 1))                # an unsigned vehicle
    with pytest.raises(LinkError, match="give --signing-key|rejected for their signature"):
        GroundLink.open(fleet.urls(), signing_key=bytes(32), expect=1, timeout_s=1.5)


# -- tlog ------------------------------------------------------------------------------------
def test_tlog_replays_with_pymavlink(fleet_of, tmp_path):
    fleet = fleet_of(fleet_config("px4", 2))
    t0 = time.time()
    with GroundLink.open(fleet.urls(), expect=2, timeout_s=10,
                         tlog=tmp_path / "flight-{sysid}.tlog"):
        time.sleep(1.5)
    t1 = time.time()
    for sysid in (1, 2):
        log = mavutil.mavlink_connection(str(tmp_path / f"flight-{sysid}.tlog"))
        kinds, stamps = set(), []
        while (msg := log.recv_match()) is not None:
            assert msg.get_srcSystem() == sysid
            kinds.add(msg.get_type())
            stamps.append(msg._timestamp)
        assert {"HEARTBEAT", "GLOBAL_POSITION_INT", "SYS_STATUS"} <= kinds
        assert t0 - 0.1 <= stamps[0] <= stamps[-1] <= t1 + 0.1
        assert stamps == sorted(stamps)


def test_what_a_real_autopilot_sends_is_read_as_it_means():
    """PX4 sends a STATUSTEXT longer than 50 characters in chunks (same id,
    chunk_seq 0, 1, ...): one text. ArduPilot's GLOBAL_POSITION_INT reads 0, 0
    until its EKF has an origin: no position yet."""
    from gcs.link import VehicleState, _update_state

    s = VehicleState()
    text = "Preflight Fail: ekf2 missing data, waiting for a GPS fix and a heading"
    for seq, start in enumerate(range(0, len(text), 50)):
        _update_state(s, build_message("STATUSTEXT", {"severity": 4, "text": text[start:start + 50].encode(),
                                                      "id": 7, "chunk_seq": seq}), "px4", 2)
    _update_state(s, build_message("STATUSTEXT", {"severity": 6, "text": b"Takeoff detected"}),
                  "px4", 2)
    assert s.statustext == [(4, text), (6, "Takeoff detected")]
    _update_state(s, build_message("GLOBAL_POSITION_INT", {"lat": 0, "lon": 0, "alt": 0}),
                  "ardupilot", 2)
    assert s.lat is None and s.alt_amsl is None
    _update_state(s, build_message("GLOBAL_POSITION_INT", {"lat": 365519720, "lon": -842666433,
                                                           "alt": 477600, "hdg": 65535}),
                  "ardupilot", 2)
    assert (round(s.lat, 7), s.alt_amsl) == (36.551972, 477.6)


def test_the_battery_is_read_from_its_own_report_first():
    """SYS_STATUS's battery_remaining until the pack's BATTERY_STATUS (id 0) is heard,
    then that one (SYS_STATUS may sum or pick among packs); -1 is unknown."""
    from gcs.link import VehicleState, _update_state

    s = VehicleState()
    _update_state(s, build_message("SYS_STATUS", {"battery_remaining": 80}), "px4", 2)
    assert s.battery_pct == 80
    _update_state(s, build_message("BATTERY_STATUS", {"id": 1, "battery_remaining": 10}),
                  "px4", 2)
    assert s.battery_pct == 80                             # another pack
    _update_state(s, build_message("BATTERY_STATUS", {"id": 0, "battery_remaining": 60}),
                  "px4", 2)
    _update_state(s, build_message("SYS_STATUS", {"battery_remaining": 55}), "px4", 2)
    assert s.battery_pct == 60
    _update_state(s, build_message("BATTERY_STATUS", {"id": 0, "battery_remaining": -1}),
                  "px4", 2)
    assert s.battery_pct == 60


def test_after_a_silence_the_battery_and_progress_are_waited_for(monkeypatch):
    """Heard again after a silence (more than `SILENCE_GAP_S` without any message), a
    vehicle's battery and mission progress are the silence's age until it reports
    them again: not caught up until both came (or `CATCH_UP_S` went by)."""
    from gcs import link as link_module
    from gcs.link import CATCH_UP_S, SILENCE_GAP_S, VehicleState, _update_state

    clock = [100.0]
    monkeypatch.setattr(link_module.time, "monotonic", lambda: clock[0])
    s = VehicleState()

    def hear(kind, fields, after_s=0.1):
        clock[0] += after_s
        _update_state(s, build_message(kind, fields), "ardupilot", 2)

    hear("SYS_STATUS", {"battery_remaining": 80})
    hear("MISSION_CURRENT", {"seq": 4})
    assert s.caught_up                                   # never silent
    hear("GLOBAL_POSITION_INT", {"lat": 365519720, "lon": -842666433, "alt": 700000,
                                 "relative_alt": 60000}, after_s=SILENCE_GAP_S + 0.5)
    assert not s.caught_up                               # a new position, old news
    hear("SYS_STATUS", {"battery_remaining": 61})
    assert not s.caught_up
    hear("MISSION_CURRENT", {"seq": 19})
    assert s.caught_up
    hear("HEARTBEAT", {"type": 2, "autopilot": 3}, after_s=SILENCE_GAP_S + 0.5)
    assert not s.caught_up
    clock[0] += CATCH_UP_S + 0.1                         # a vehicle that streams neither
    assert s.caught_up
