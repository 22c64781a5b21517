# Over 600 lines, knowingly: the fleet's connections, the HEARTBEAT discovery and the routed
# sends share one receive thread and its per-system queues; split, each part would reach into them.
"""MAVLink links to a fleet: connections, vehicles found by HEARTBEAT, routed sends.

    link = GroundLink.open(["udpin:0.0.0.0:14550"], expect=4, timeout_s=10)
    v = link.vehicles[2]                      # VehicleLink, by system id
    v.send("MISSION_REQUEST_LIST", mission_type=0)
    count = v.recv("MISSION_COUNT", timeout=1.5)
    v.state.mode, v.state.lat, v.state.armed
    link.close()

URLs are pymavlink's (`tcp:HOST:PORT`, `udpin:HOST:PORT`, `udpout:HOST:PORT`,
`/dev/ttyACM0,57600`). One reader thread per connection parses bytes itself
(instead of pymavlink's `recv_match`) for two reasons: several PX4 instances
send to one `udpin` port from different source ports, and pymavlink would
answer whoever spoke last, so we keep each system id's own address and send
with the socket directly; and each UDP peer gets its own parser, so packets of
different senders never mix in one parse buffer.
"""

import collections
import itertools
import re
import select
import socket
import struct
import threading
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

from gcs import signing
from gcs.mavlink import (
    GCS_COMPONENT_ID,
    GCS_SYSTEM_ID,
    M,
    flavour_of,
    mavutil,
    mode_name,
    profile_of,
)

HEARTBEAT_PERIOD_S = 1.0
#: the ground station's HEARTBEAT comes once a second of the vehicles' own time, this
#: often at most: a SITL sped up 10x with its link failsafe on (FS_GCS_TIMEOUT 5 s)
#: fired it between two HEARTBEATs a wall second apart, and disarmed on its pad
HEARTBEAT_MIN_S = 0.05
#: wall s over which a vehicle's own clock rate is measured
CLOCK_SPAN_S = 2.0
#: wall seconds without any message from a vehicle that make a silence (its streams
#: come several times a second, its HEARTBEAT once)
SILENCE_GAP_S = 1.0
#: wall seconds after a silence its battery and mission progress are waited for at most
#: (ArduPilot and PX4 stream both at least once a second)
CATCH_UP_S = 5.0
STREAM_RATE_HZ = 4               # telemetry asked of ArduPilot, as MAVProxy's default
#: what a requested stream carries (TIMESYNC, STATUSTEXT flow before any request)
STREAMED = frozenset({"SYS_STATUS", "GLOBAL_POSITION_INT", "GPS_RAW_INT"})
STREAM_RETRY_S = 2.0             # streams asked again after this long with HEARTBEATs only
POLL_S = 0.05
#: wall seconds between attempts to connect again to a TCP peer that closed: an
#: autopilot rebooting (a battery swap powers it down) serves its port again
RECONNECT_S = 1.0
QUEUE_DEPTH = 500            # messages kept per type and vehicle for recv()
STATUSTEXT_KEPT = 20
# Heartbeats of these are never vehicles: ground stations, cameras, gimbals, companions.
NOT_VEHICLES = frozenset({M.MAV_TYPE_GCS, M.MAV_TYPE_GIMBAL, M.MAV_TYPE_CAMERA,
                          M.MAV_TYPE_ONBOARD_CONTROLLER, M.MAV_TYPE_ADSB,
                          M.MAV_TYPE_ANTENNA_TRACKER, M.MAV_TYPE_SERVO,
                          M.MAV_TYPE_ODID, M.MAV_TYPE_BATTERY, M.MAV_TYPE_FLARM,
                          M.MAV_TYPE_PARACHUTE, M.MAV_TYPE_LOG, M.MAV_TYPE_OSD,
                          M.MAV_TYPE_IMU, M.MAV_TYPE_GPS, M.MAV_TYPE_WINCH})


class LinkError(Exception):
    """A connection could not be opened, or the expected vehicles did not show up."""


# -- vehicle state ---------------------------------------------------------------------
@dataclass
class VehicleState:
    """What the telemetry says about one vehicle; updated by the reader thread."""
    lat: float | None = None                 # deg
    lon: float | None = None                 # deg
    alt_amsl: float | None = None            # m
    relative_alt: float | None = None        # m above home
    heading: float | None = None             # deg
    groundspeed: float | None = None         # m/s
    velocity: tuple | None = None            # (north, east, up) m/s, GLOBAL_POSITION_INT
    position_at: float | None = None         # time.monotonic() of the last position
    boot_s: float | None = None              # the autopilot's own clock (s since boot)
    boot_at: float | None = None             # in its latest report, at time.monotonic()
    clock_rate: float = 1.0                  # its clock's s per wall s (a sped-up SITL)
    clock_ref: tuple | None = None           # (boot_s, boot_at) it is measured from
    armed: bool = False
    mode: str | None = None
    custom_mode: int | None = None
    system_status: int | None = None         # MAV_STATE
    mission_seq: int | None = None           # MISSION_CURRENT.seq
    mission_total: int | None = None
    reached: list = field(default_factory=list)   # MISSION_ITEM_REACHED seqs, in order
    last_heartbeat: float | None = None      # time.monotonic() of the last HEARTBEAT
    landed: bool | None = None               # EXTENDED_SYS_STATE (None: not reported)
    ready: bool = False                      # pre-arm checks / EKF / GPS good
    gps_fix: int = 0                         # GPS_RAW_INT.fix_type
    battery_pct: int | None = None           # remaining: BATTERY_STATUS of the first
                                             # pack, else SYS_STATUS
    battery_status: bool = False             # BATTERY_STATUS of the first pack seen
    battery_by_s: float | None = None        # the vehicle's clock at its first report
                                             # after battery_pct came (None: none yet):
                                             # the charge is of that time or earlier
    home: tuple | None = None                # (lat, lon, alt AMSL) from HOME_POSITION
    heard_at: float | None = None            # time.monotonic() of its last message
    back_at: float | None = None             # ... of the first after its last silence
    battery_at: float | None = None          # ... of its last battery reading
    current_at: float | None = None          # ... of its last MISSION_CURRENT
    images: int = 0                          # CAMERA_FEEDBACK / CAMERA_IMAGE_CAPTURED seen
    statustext: list = field(default_factory=list)   # last (severity, text)
    text_chunk: int = 0                      # STATUSTEXT.id of the last one (chunks)

    @property
    def caught_up(self) -> bool:
        """Its battery and its mission's current item reported since it was last heard
        again after a silence (or `CATCH_UP_S` gone by: a vehicle that streams
        neither): until then, what it reported of them is as old as the silence
        (heard again after 200 s of flight, a vehicle's position was new, its
        battery 4 minutes old and its progress 5 minutes behind)."""
        if self.back_at is None or time.monotonic() - self.back_at > CATCH_UP_S:
            return True
        return (self.battery_at or 0.0) >= self.back_at and \
            (self.current_at or 0.0) >= self.back_at


def _measure_clock(s: VehicleState) -> None:
    """The vehicle's clock rate over the last `CLOCK_SPAN_S` of wall time (a reboot,
    its clock going back, starts again)."""
    ref = s.clock_ref
    if ref is None or s.boot_s < ref[0]:
        s.clock_ref = (s.boot_s, s.boot_at)
    elif s.boot_at - ref[1] >= CLOCK_SPAN_S:
        s.clock_rate = max((s.boot_s - ref[0]) / (s.boot_at - ref[1]), 1e-3)
        s.clock_ref = (s.boot_s, s.boot_at)


def _update_state(s: VehicleState, msg, flavour: str, mav_type: int) -> None:
    kind = msg.get_type()
    now = time.monotonic()
    if s.heard_at is not None and now - s.heard_at > SILENCE_GAP_S:
        s.back_at = now
    s.heard_at = now
    boot_ms = getattr(msg, "time_boot_ms", None)
    if boot_ms:
        s.boot_s, s.boot_at = boot_ms * 1e-3, time.monotonic()
        if s.battery_by_s is None:
            s.battery_by_s = s.boot_s
        _measure_clock(s)
    if kind == "HEARTBEAT":
        s.last_heartbeat = time.monotonic()
        s.armed = bool(msg.base_mode & M.MAV_MODE_FLAG_SAFETY_ARMED)
        s.custom_mode = msg.custom_mode
        s.mode = mode_name(flavour, msg.custom_mode, mav_type)
        s.system_status = msg.system_status
    elif kind == "GLOBAL_POSITION_INT":
        if not has_position(msg):
            return                     # ArduPilot before its EKF origin: no position yet
        s.lat, s.lon = msg.lat * 1e-7, msg.lon * 1e-7
        s.alt_amsl, s.relative_alt = msg.alt * 1e-3, msg.relative_alt * 1e-3
        if msg.hdg != 65535:
            s.heading = msg.hdg * 0.01
        s.groundspeed = (msg.vx ** 2 + msg.vy ** 2) ** 0.5 * 0.01
        s.velocity = (msg.vx * 0.01, msg.vy * 0.01, -msg.vz * 0.01)
        s.position_at = time.monotonic()
    elif kind == "MISSION_CURRENT":
        s.mission_seq, s.mission_total = msg.seq, getattr(msg, "total", None)
        s.current_at = now
    elif kind == "MISSION_ITEM_REACHED":
        s.reached.append(msg.seq)
    elif kind == "EXTENDED_SYS_STATE":
        if msg.landed_state != M.MAV_LANDED_STATE_UNDEFINED:
            s.landed = msg.landed_state == M.MAV_LANDED_STATE_ON_GROUND
    elif kind == "SYS_STATUS":
        if not s.battery_status:
            s.battery_pct = None if msg.battery_remaining < 0 else msg.battery_remaining
            s.battery_by_s, s.battery_at = None, now
        s.ready = _prearm_ok(msg, s.gps_fix)
    elif kind == "BATTERY_STATUS" and msg.id == 0 and msg.battery_remaining >= 0:
        # the pack's own report (SYS_STATUS may sum or pick among several packs)
        s.battery_pct, s.battery_status = msg.battery_remaining, True
        s.battery_by_s, s.battery_at = None, now
    elif kind == "GPS_RAW_INT":
        s.gps_fix = msg.fix_type
    elif kind == "HOME_POSITION":
        s.home = (msg.latitude * 1e-7, msg.longitude * 1e-7, msg.altitude * 1e-3)
    elif kind in ("CAMERA_FEEDBACK", "CAMERA_IMAGE_CAPTURED"):
        s.images += 1
    elif kind == "STATUSTEXT":
        chunk = getattr(msg, "id", 0)
        if chunk and getattr(msg, "chunk_seq", 0) > 0 and s.statustext \
                and s.text_chunk == chunk:     # PX4 sends a long text in 50-char chunks
            severity, text = s.statustext[-1]
            s.statustext = s.statustext[:-1] + [(severity, text + msg.text)]
        else:
            s.statustext = (s.statustext + [(msg.severity, msg.text)])[-STATUSTEXT_KEPT:]
        s.text_chunk = chunk


def has_position(msg) -> bool:
    """A GLOBAL_POSITION_INT that holds a position: ArduPilot reports 0, 0 until its
    EKF has an origin (about 20 s after boot)."""
    return not (msg.lat == 0 and msg.lon == 0)


def _prearm_ok(msg, gps_fix: int) -> bool:
    """Ready to arm: the pre-arm check bit where reported, else GPS 3D fix and AHRS healthy."""
    prearm = M.MAV_SYS_STATUS_PREARM_CHECK
    if msg.onboard_control_sensors_present & prearm:
        return bool(msg.onboard_control_sensors_health & prearm)
    ahrs = M.MAV_SYS_STATUS_AHRS
    ahrs_ok = not msg.onboard_control_sensors_present & ahrs or \
        bool(msg.onboard_control_sensors_health & ahrs)
    return gps_fix >= M.GPS_FIX_TYPE_3D_FIX and ahrs_ok


# -- tlog ------------------------------------------------------------------------------
class TlogWriter:
    """`.tlog` as MAVProxy / QGroundControl write it: 8-byte big-endian microseconds
    since 1970, then the raw packet. `{sysid}` in the path gives one file per vehicle."""

    def __init__(self, path):
        self._pattern = str(path)
        self._files = {}
        self._lock = threading.Lock()

    def write(self, sysid: int, packet: bytes, t: float | None = None) -> None:
        stamp = struct.pack(">Q", int((time.time() if t is None else t) * 1e6))
        path = self._pattern.format(sysid=sysid) if "{sysid}" in self._pattern \
            else self._pattern
        with self._lock:
            f = self._files.get(path)
            if f is None:
                Path(path).parent.mkdir(parents=True, exist_ok=True)
                f = self._files[path] = open(path, "ab")
            f.write(stamp + packet)

    def flush(self) -> None:
        with self._lock:
            for f in self._files.values():
                f.flush()

    def close(self) -> None:
        with self._lock:
            for f in self._files.values():
                f.close()
            self._files = {}


# -- one connection --------------------------------------------------------------------
def _parser(signing_key: bytes | None, link_id: int = 0):
    """A MAVLink object for packing or parsing; with a key it signs and requires
    signatures (`gcs.signing.apply`)."""
    mav = M.MAVLink(None, srcSystem=GCS_SYSTEM_ID, srcComponent=GCS_COMPONENT_ID)
    mav.robust_parsing = True
    signing.apply(mav, signing_key, link_id)
    return mav


def _split_serial(url: str) -> tuple:
    """"/dev/ttyACM0,57600" -> ("/dev/ttyACM0", 57600); other URLs keep baud 115200."""
    head, sep, tail = url.rpartition(",")
    if sep and tail.isdigit():
        return head, int(tail)
    return url, 115200


#: network URL schemes pymavlink opens, and what each means
SCHEMES = ("tcp:", "udp:", "udpin:", "udpout:", "udpbcast:")
URL_FORMS = ("tcp:HOST:PORT (connect), udpin:HOST:PORT (listen), udpout:HOST:PORT (send to), "
             "udpbcast:HOST:PORT, or a serial DEVICE,BAUD (/dev/ttyUSB0,57600; COM3,57600)")


def parse_url(url: str) -> tuple:
    """(device, baud) of a connection URL in a form pymavlink takes; LinkError
    otherwise. A bare HOST:PORT is refused: pymavlink would read it as UDP (and
    listen), not the TCP of ArduPilot SITL, and wait for nothing."""
    url = url.strip()
    if url.startswith(SCHEMES):
        scheme, _, rest = url.partition(":")
        host, sep, port = rest.rpartition(":")
        if not sep or not host or not port.isdigit():
            raise LinkError(f"{url}: expected {scheme}:HOST:PORT")
        return url, 115200
    head, comma, tail = url.rpartition(",")
    device = head if comma else url
    serial_like = (device.startswith("/") and ":" not in device) or \
        re.fullmatch(r"(COM\d+|\\\\\.\\COM\d+)", device, re.IGNORECASE) is not None
    if serial_like:
        if comma and not tail.isdigit():
            raise LinkError(f"{url}: the baud rate after the comma is not a number")
        return _split_serial(url)
    hint = ""
    if ":" in url and url.rpartition(":")[2].isdigit():
        hint = f" (for ArduPilot SITL: tcp:{url}; to listen: udpin:{url})"
    raise LinkError(f"{url}: not a connection URL{hint}; pymavlink takes {URL_FORMS}")


class Connection:
    """One pymavlink endpoint, read as raw bytes with the sender's address."""

    def __init__(self, url: str, signing_key: bytes | None = None, link_id: int = 0):
        self.url = url
        self._device = parse_url(url)
        try:
            self.conn = self._connect()
        except (OSError, ValueError) as exc:
            raise LinkError(f"{url}: cannot open: {exc}") from exc
        except ImportError as exc:      # pymavlink imports pyserial only for serial links
            raise LinkError(f"{url}: cannot open a serial link: {exc} (install pyserial)") \
                from exc
        except Exception as exc:        # pyserial's SerialException is an OSError subclass;
            if type(exc).__name__ != "SerialException":   # anything else is a bug
                raise
            raise LinkError(f"{url}: cannot open: {exc}") from exc
        self.kind = self._kind(self._device[0])
        self._key, self._link_id = signing_key, link_id
        self._parsers = {}              # sender address -> MAVLink parser
        self.peers = []                 # udpin: every address that sent us anything
        self.closed = False
        self.shut = False               # closed by us: never opened again
        self.reconnects = 0             # TCP peers that closed and were connected again
        self._retry_at = 0.0
        self.rejected = 0               # packets dropped for a missing / bad signature
        self.received = 0

    def _connect(self):
        device, baud = self._device
        return mavutil.mavlink_connection(
            device, baud=baud, source_system=GCS_SYSTEM_ID, source_component=GCS_COMPONENT_ID,
            autoreconnect=False, retries=1, reconnect_delay=0.2)

    def _reconnect(self) -> bool:
        """A TCP peer that closed (an autopilot rebooting) connected to again, once
        every `RECONNECT_S`; a serial or UDP link stays open across a reboot."""
        now = time.monotonic()
        if self.shut or not self._device[0].startswith("tcp:") or now < self._retry_at:
            return False
        self._retry_at = now + RECONNECT_S
        try:
            conn = self._connect()
        except OSError:
            return False
        old, self.conn = self.conn, conn
        try:
            old.close()
        except OSError:
            pass
        self._parsers = {}              # a new byte stream
        self.reconnects += 1
        self.closed = False
        return True

    @staticmethod
    def _kind(device: str) -> str:
        if device.startswith(("udpin:", "udp:")):
            return "udpin"
        if device.startswith(("udpout:", "udpbcast:")):
            return "udpout"
        return "stream"

    def fileno(self):
        if self.kind != "stream":
            return self.conn.port.fileno()
        return getattr(self.conn, "fd", None)

    def read(self, timeout: float) -> list:
        """Wait up to `timeout` s; return [(message, sender address)] that parsed."""
        if self.closed and not self._reconnect():
            time.sleep(timeout)
            return []
        fd = self.fileno()
        if fd is not None:
            try:
                ready, _, _ = select.select([fd], [], [], timeout)
            except (OSError, ValueError):
                self.closed = True
                return []
            if not ready:
                return []
        out = []
        for data, addr in self._chunks():
            mav = self._parsers.get(addr)
            if mav is None:
                mav = self._parsers[addr] = _parser(self._key, self._link_id)
                if self.kind == "udpin":
                    self.peers.append(addr)
            for msg in mav.parse_buffer(data) or []:
                if msg.get_type() == "BAD_DATA":
                    self.rejected += signing.is_signature_reject(msg)
                    continue
                self.received += 1
                out.append((msg, addr))
        if fd is None and not out:
            time.sleep(min(timeout, 0.01))
        return out

    def _chunks(self) -> list:
        if self.kind != "stream":
            chunks = []
            while True:
                try:
                    chunks.append(self.conn.port.recvfrom(65536))
                except (BlockingIOError, InterruptedError):
                    return chunks
                except OSError:       # ICMP port unreachable from a udpout peer: keep going
                    return chunks
        port = getattr(self.conn, "port", None)
        try:
            if isinstance(port, socket.socket):
                data = port.recv(65536)      # pymavlink's recv prints on EOF
            else:
                data = self.conn.recv(65536)
        except (BlockingIOError, InterruptedError):
            return []
        except OSError:
            data = b""
            self.closed = True
        if not data and self.fileno() is not None and self.kind == "stream":
            self.closed = True        # readable but empty: the peer closed the socket
            return []
        return [(bytes(data), None)] if data else []

    def write(self, packet: bytes, addr=None) -> None:
        if self.closed:
            return
        try:
            if self.kind == "udpin":
                for a in ([addr] if addr is not None else list(self.peers)):
                    self.conn.port.sendto(packet, a)
            else:
                self.conn.write(packet)
        except OSError:
            if self.kind == "stream":
                self.closed = True

    def close(self) -> None:
        self.closed = self.shut = True
        try:
            self.conn.close()
        except OSError:
            pass


# -- one vehicle -----------------------------------------------------------------------
#: acknowledged commands whose round trips a link keeps
ROUND_TRIPS_KEPT = 16


class VehicleLink:
    """One vehicle (system id) on a GroundLink: its messages, its state, routed sends."""

    def __init__(self, ground: "GroundLink", sysid: int, compid: int, heartbeat,
                 conn: Connection, addr):
        self.ground = ground
        self.sysid, self.compid = sysid, compid
        self.autopilot = heartbeat.autopilot
        self.mav_type = heartbeat.type
        self.flavour = flavour_of(heartbeat.autopilot)
        self.profile = profile_of(self.flavour)     # autopilots profile; None: generic
        self.state = VehicleState()
        self.signs = False            # its packets carry signatures (seen without a key)
        self.mission_capacity = None  # items it holds, once learned (mission_protocol)
        self.mission_fits = 0         # the longest upload it took
        # wall s from sending a command to its acknowledgement, the latest few (`commands`)
        self.round_trips = collections.deque(maxlen=ROUND_TRIPS_KEPT)
        self._streamed_at, self._asked_at = 0.0, 0.0   # last telemetry, request (monotonic)
        self._route = (conn, addr)
        self._queues = collections.defaultdict(lambda: collections.deque(maxlen=QUEUE_DEPTH))
        self._cond = threading.Condition()
        self._subscribers = []

    def __repr__(self) -> str:
        return f"VehicleLink(sysid={self.sysid}, flavour={self.flavour!r})"

    @property
    def name(self) -> str:
        return f"vehicle {self.sysid}"

    @property
    def connection(self) -> Connection:
        return self._route[0]

    # -- sending ------------------------------------------------------------------
    def send(self, name: str, **fields) -> None:
        """Send message `name` (e.g. "COMMAND_LONG") to this vehicle.

        target_system / target_component default to this vehicle's; other fields not
        given are zero."""
        msg = build_message(name, dict({"target_system": self.sysid,
                                        "target_component": self.compid}, **fields))
        self.send_msg(msg)

    def request_streams(self, rate_hz: int = STREAM_RATE_HZ) -> None:
        """Ask for telemetry: ArduPilot streams on a port only what a ground station
        requests (MAVProxy does the same); PX4 streams to its GCS link by itself,
        and the profile's ``message_rates`` slow what it sends faster than read.
        Fire and forget: this runs on the reader thread, which must not wait."""
        if self.profile is None:
            return
        self._asked_at = time.monotonic()
        if self.profile.request_streams:
            self.send("REQUEST_DATA_STREAM", req_stream_id=M.MAV_DATA_STREAM_ALL,
                      req_message_rate=rate_hz, start_stop=1)
        for message, hz in self.profile.message_rates:
            self.send("COMMAND_LONG", command=M.MAV_CMD_SET_MESSAGE_INTERVAL,
                      param1=float(message), param2=1e6 / hz if hz > 0 else -1.0)

    def send_msg(self, msg) -> None:
        conn, addr = self._route
        self.ground._transmit(conn, msg, addr)

    # -- receiving ----------------------------------------------------------------
    def recv(self, types, timeout: float, condition=None):
        """The oldest queued message of `types` (a name or a list) for which
        `condition(msg)` holds, waiting up to `timeout` s; None on timeout.

        Messages of other types stay queued; what is returned is removed."""
        types = (types,) if isinstance(types, str) else tuple(types)
        deadline = time.monotonic() + timeout
        with self._cond:
            while True:
                msg = self._take(types, condition)
                if msg is not None:
                    return msg
                left = deadline - time.monotonic()
                if left <= 0:
                    return None
                self._cond.wait(left)

    def _take(self, types, condition):
        best = None
        for t in types:
            queue = self._queues.get(t)
            if not queue:
                continue
            for entry in queue:
                if condition is None or condition(entry[1]):
                    if best is None or entry[0] < best[0][0]:
                        best = (entry, queue)
                    break
        if best is None:
            return None
        entry, queue = best
        queue.remove(entry)
        return entry[1]

    def flush(self, types=None) -> None:
        """Forget queued messages (of `types`, or all): start an exchange afresh."""
        with self._cond:
            if types is None:
                self._queues.clear()
            else:
                for t in (types,) if isinstance(types, str) else types:
                    self._queues.pop(t, None)

    def subscribe(self, callback):
        """Call `callback(msg)` from the reader thread for every message of this
        vehicle (after `state` is updated); returns a function that unsubscribes."""
        self._subscribers.append(callback)
        return lambda: self._subscribers.remove(callback) if callback in self._subscribers \
            else None

    def snapshot(self) -> VehicleState:
        """A consistent copy of `state`."""
        with self._cond:
            return replace(self.state, reached=list(self.state.reached),
                           statustext=list(self.state.statustext))

    def heartbeat_age(self) -> float:
        """Seconds since the last HEARTBEAT (inf if none)."""
        last = self.state.last_heartbeat
        return float("inf") if last is None else time.monotonic() - last

    def silent_s(self) -> float:
        """Seconds since anything was heard from its autopilot (inf if nothing): a
        link back after a silence brings positions up to a second before the next
        HEARTBEAT (one heard again 4.4 s into a silence was lost at 5 s, by its
        HEARTBEAT's age, while its positions came)."""
        last = self.state.heard_at
        return float("inf") if last is None else time.monotonic() - last

    def _deliver(self, msg, index: int, conn, addr) -> None:
        from_autopilot = msg.get_srcComponent() == self.compid
        with self._cond:
            if from_autopilot:
                self._route = (conn, addr)
                self.signs = _is_signed(msg)
                _update_state(self.state, msg, self.flavour, self.mav_type)
                ask_again = self._streams_missing(msg)
            if _addressed_to_us(msg):
                self._queues[msg.get_type()].append((index, msg))
                self._cond.notify_all()
        if from_autopilot and ask_again:
            self.request_streams()
        for callback in list(self._subscribers):
            try:
                callback(msg)
            except Exception:    # a broken subscriber must not stop the reader thread
                pass

    def _streams_missing(self, msg) -> bool:
        """True on a HEARTBEAT when no telemetry has come for STREAM_RETRY_S, that
        long after the last request: that request was lost on the way, as packets
        are on a radio link, or the autopilot rebooted (a battery swap powers it
        down; ArduPilot SITL is back within a second at 10x), and it streams
        nothing until asked again."""
        now = time.monotonic()
        if msg.get_type() in STREAMED:
            self._streamed_at = now
        if msg.get_type() != "HEARTBEAT":
            return False
        return now - max(self._streamed_at, self._asked_at) >= STREAM_RETRY_S


def _is_signed(msg) -> bool:
    buf = msg.get_msgbuf()
    return len(buf) > 2 and buf[0] == 0xFD and bool(buf[2] & M.MAVLINK_IFLAG_SIGNED)


def _addressed_to_us(msg) -> bool:
    target = getattr(msg, "target_system", 0)
    return target in (0, GCS_SYSTEM_ID)


def build_message(name: str, fields: dict):
    """A pymavlink message by name; fields not given are zero (arrays: zeros)."""
    cls = M.mavlink_map.get(getattr(M, f"MAVLINK_MSG_ID_{name.upper()}", -1))
    if cls is None:
        raise ValueError(f"unknown MAVLink message {name!r}")
    values = []
    for fname, ftype, length in zip(cls.fieldnames, cls.fieldtypes, cls.array_lengths):
        if fname in fields:
            values.append(fields[fname])
        elif ftype == "char":
            values.append(b"")
        else:
            values.append([0] * length if length else 0)
    unknown = set(fields) - set(cls.fieldnames)
    if unknown - {"target_system", "target_component"}:
        raise ValueError(f"{name}: unknown fields {sorted(unknown)}")
    return cls(*values)


# -- the fleet -------------------------------------------------------------------------
class GroundLink:
    """The ground station's side of every connection, and the vehicles found on them."""

    def __init__(self, urls, signing_key: bytes | None = None, tlog=None, forward=None):
        """``forward``: a `gcs.forward.Forwarder` that every vehicle message is relayed
        to (and that reads the forwarded side); closed with the link."""
        if isinstance(urls, str):
            urls = [urls]
        self.signing_key = signing_key
        self.forward = forward
        self.connections = []
        self._vehicles = {}
        self._lock = threading.Lock()
        self._send_lock = threading.Lock()
        self._packer = _parser(signing_key)
        self._counter = itertools.count()
        self._stop = threading.Event()
        self._threads = []
        self._tlog = TlogWriter(tlog) if tlog else None
        self._new_vehicle = threading.Condition(self._lock)
        try:
            for i, url in enumerate(urls):
                self.connections.append(Connection(url, signing_key, link_id=i))
        except LinkError:
            self._close_connections()
            raise

    @classmethod
    def open(cls, urls, signing_key: bytes | None = None, expect=None, timeout_s: float = 10,
             tlog=None, forward=None) -> "GroundLink":
        """Connect to `urls` and wait for vehicles.

        expect: a number of vehicles, or an iterable of system ids, to wait for; None
        waits until every connection has shown one vehicle and then one more
        heartbeat period for others sharing a port. Raises LinkError naming what is
        missing after `timeout_s`."""
        link = cls(urls, signing_key, tlog, forward)
        link.start()
        try:
            link.wait_vehicles(expect, timeout_s)
        except LinkError:
            link.close()
            raise
        return link

    def start(self) -> "GroundLink":
        for conn in self.connections:
            t = threading.Thread(target=self._reader, args=(conn,), daemon=True,
                                 name=f"mavlink-reader {conn.url}")
            t.start()
            self._threads.append(t)
        t = threading.Thread(target=self._heartbeats, daemon=True, name="gcs-heartbeat")
        t.start()
        self._threads.append(t)
        if self.forward is not None:
            self.forward.start(self)
        return self

    @property
    def vehicles(self) -> dict:
        """{sysid: VehicleLink} of every vehicle seen so far, by system id."""
        with self._lock:
            return dict(sorted(self._vehicles.items()))

    def wait_vehicles(self, expect=None, timeout_s: float = 10) -> dict:
        deadline = time.monotonic() + timeout_s
        settle = None
        with self._new_vehicle:
            while True:
                if self._enough(expect):
                    if expect is not None:
                        break
                    settle = settle or time.monotonic() + 1.5 * HEARTBEAT_PERIOD_S
                    if time.monotonic() >= settle:
                        break
                left = deadline - time.monotonic()
                if left <= 0:
                    if expect is None and self._vehicles:
                        break
                    raise LinkError(self._missing(expect, timeout_s))
                self._new_vehicle.wait(min(left, settle - time.monotonic()) if settle
                                       else left)
        return self.vehicles

    def _enough(self, expect) -> bool:
        found = set(self._vehicles)
        if expect is None:
            seen = {v.connection for v in self._vehicles.values()}
            return all(c in seen for c in self.connections)
        if isinstance(expect, int):
            return len(found) >= expect
        return set(expect) <= found

    def _missing(self, expect, timeout_s) -> str:
        found = sorted(self._vehicles)
        if isinstance(expect, int):
            what = f"{expect} vehicle(s), found {len(found)} {found}"
        elif expect is not None:
            what = f"system id(s) {sorted(set(expect) - set(found))}"
        else:
            what = "a vehicle on " + ", ".join(c.url for c in self.connections
                                              if c not in {v.connection for v in
                                                           self._vehicles.values()})
        text = f"no HEARTBEAT from {what} within {timeout_s:g} s"
        rejected = sum(c.rejected for c in self.connections)
        if rejected:
            key = "the signing key differs from the vehicle's" if self.signing_key \
                else "the vehicle signs its messages: give --signing-key"
            text += f"; {rejected} packets rejected for their signature ({key})"
        elif not any(c.received for c in self.connections):
            text += " (nothing received at all: check the URL, port and cabling)"
        return text

    # -- sending ------------------------------------------------------------------
    def _transmit(self, conn: Connection, msg, addr=None) -> None:
        # sequence numbers and signing timestamps, and the write too: a signed packet
        # overtaken by a later-stamped one is dropped by the vehicle as a replay
        with self._send_lock:
            packet = bytes(msg.pack(self._packer))
            self._packer.seq = (self._packer.seq + 1) % 256
            conn.write(packet, addr)

    def _write_raw(self, conn: Connection, packet: bytes, addr=None) -> None:
        """Write a packet someone else packed (a forwarded station's), as it is."""
        with self._send_lock:
            conn.write(packet, addr)

    def _heartbeats(self) -> None:
        hb = build_message("HEARTBEAT", {"type": M.MAV_TYPE_GCS,
                                         "autopilot": M.MAV_AUTOPILOT_INVALID,
                                         "system_status": M.MAV_STATE_ACTIVE,
                                         "mavlink_version": 3})
        while not self._stop.is_set():
            for conn in self.connections:
                self._transmit(conn, hb)       # udpin: to every peer heard from
            if self._tlog is not None:
                self._tlog.flush()             # a crash loses at most a second of log
            self._stop.wait(self._heartbeat_period())

    def _heartbeat_period(self) -> float:
        """Wall s to the next HEARTBEAT: a second of the fastest vehicle's own clock."""
        with self._lock:
            rates = [v.state.clock_rate for v in self._vehicles.values()]
        return max(HEARTBEAT_PERIOD_S / max([1.0, *rates]), HEARTBEAT_MIN_S)

    # -- receiving ----------------------------------------------------------------
    def _reader(self, conn: Connection) -> None:
        while not self._stop.is_set():
            for msg, addr in conn.read(POLL_S):
                self._dispatch(msg, conn, addr)

    def _dispatch(self, msg, conn, addr) -> None:
        sysid = msg.get_srcSystem()
        vehicle = self._vehicles.get(sysid)
        if vehicle is None:
            self._discover(msg, conn, addr)
        else:
            self._deliver(vehicle, msg, conn, addr)

    def _deliver(self, vehicle, msg, conn, addr) -> None:
        if self._tlog is not None:
            self._tlog.write(vehicle.sysid, bytes(msg.get_msgbuf()))
        vehicle._deliver(msg, next(self._counter), conn, addr)
        if self.forward is not None:
            self.forward.relay(vehicle, msg)

    def _discover(self, msg, conn, addr) -> None:
        """A HEARTBEAT from an autopilot makes a vehicle; everything else waits for one.
        The HEARTBEAT is delivered before the vehicle is published: one seen
        without it would look silent since forever (and be declared lost)."""
        if msg.get_type() != "HEARTBEAT" or msg.autopilot == M.MAV_AUTOPILOT_INVALID \
                or msg.type in NOT_VEHICLES:
            return
        with self._new_vehicle:
            vehicle = self._vehicles.get(msg.get_srcSystem())
            if vehicle is not None:       # found meanwhile on another connection
                self._deliver(vehicle, msg, conn, addr)
                return
            vehicle = VehicleLink(self, msg.get_srcSystem(), msg.get_srcComponent(),
                                  msg, conn, addr)
            self._deliver(vehicle, msg, conn, addr)
            self._vehicles[vehicle.sysid] = vehicle
            self._new_vehicle.notify_all()
            vehicle.request_streams()

    # -- closing ------------------------------------------------------------------
    def close(self) -> None:
        self._stop.set()
        for t in self._threads:
            t.join(timeout=2)
        self._threads = []
        self._close_connections()
        if self.forward is not None:
            self.forward.close()
        if self._tlog is not None:
            self._tlog.close()

    def _close_connections(self) -> None:
        for conn in self.connections:
            conn.close()

    def __enter__(self) -> "GroundLink":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
