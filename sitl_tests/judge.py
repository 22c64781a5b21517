"""What an autopilot reports of itself on a link of its own: the judge of a flight.

`gcs fly` talks to each vehicle on its ground-station link; the judge listens on
the autopilot's second link, which gcs never touches, and keeps what the
autopilot says of itself: its positions (GLOBAL_POSITION_INT), its mode
(HEARTBEAT's custom_mode, at each change), where its
camera fired (ArduPilot CAMERA_FEEDBACK, PX4 CAMERA_IMAGE_CAPTURED) and the
battery it reports (SYS_STATUS). On ArduPilot's link it also plays the crew
that swaps a battery between sorties (`Judge.command`: MAV_CMD_BATTERY_RESET, or
MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN: a swap that powers the autopilot down; the judge
connects again when it is back).

- ArduPilot SITL instance i: SERIAL1 on TCP 5762 + 10 i, open once its first
  port has a client; it streams what is asked (REQUEST_DATA_STREAM).
- PX4 SITL instance i: its onboard link sends to UDP 14540 + i from 14580 + i,
  at up to 50 Hz of simulated time per stream; the judge slows GLOBAL_POSITION_INT
  to 10 Hz on that link and decodes only the messages it keeps.
"""

import socket
import struct
import threading
import time

import numpy as np

from gcs.mavlink import M

HEARTBEAT, STATUS, POSITION, FEEDBACK, CAPTURED = 0, 1, 33, 180, 263
WANTED = frozenset({HEARTBEAT, STATUS, POSITION, FEEDBACK, CAPTURED})
JUDGE_SYSID = 254          # not 255: ArduPilot forwards between its links
RATE_HZ = 10


def listening(port: int) -> bool:
    """Whether a local TCP port is in LISTEN, without connecting (ArduPilot SITL
    gives its port to the first client that connects)."""
    suffix = f":{port:04X}"
    for name in ("/proc/net/tcp", "/proc/net/tcp6"):
        try:
            lines = open(name).read().splitlines()[1:]
        except OSError:
            continue
        for line in lines:
            fields = line.split()
            if fields[1].endswith(suffix) and fields[3] == "0A":
                return True
    return False


def wait_listening(port: int, timeout_s: float, alive=lambda: True) -> None:
    end = time.monotonic() + timeout_s
    while not listening(port):
        if time.monotonic() > end or not alive():
            raise RuntimeError(f"nothing listens on TCP {port} after {timeout_s:g} s")
        time.sleep(0.05)


def frames(buf: bytes):
    """(MAVLink frames [(msgid, sysid, bytes)], bytes left over) of a byte stream,
    without decoding their payloads (PX4 sends thousands a second)."""
    out, i, n = [], 0, len(buf)
    while i < n:
        b = buf[i]
        if b == 0xFD:                                  # MAVLink 2
            if i + 10 > n:
                break
            total = 12 + buf[i + 1] + (13 if buf[i + 2] & 1 else 0)
            if i + total > n:
                break
            out.append((buf[i + 7] | buf[i + 8] << 8 | buf[i + 9] << 16, buf[i + 5],
                        buf[i:i + total]))
            i += total
        elif b == 0xFE:                                # MAVLink 1
            if i + 6 > n:
                break
            total = 8 + buf[i + 1]
            if i + total > n:
                break
            out.append((buf[i + 5], buf[i + 3], buf[i:i + total]))
            i += total
        else:
            i += 1
    return out, buf[i:]


class Judge:
    """Positions and camera shots one autopilot reports on its second link."""

    def __init__(self, sysid: int, home: tuple):
        self.sysid, self.home = sysid, home
        self.samples = []                  # (wall t, lat, lon, alt AMSL)
        self.shots = []                    # (lat, lon, alt AMSL)
        self.battery = []                  # (wall t, % remaining)
        self.clock = []                    # (wall t, the autopilot's own s since boot)
        self.modes = []                    # (wall t, custom_mode): each change of mode
        self._send = None                  # bytes -> None on its link, once connected
        self._mav = M.MAVLink(None, srcSystem=JUDGE_SYSID, srcComponent=190)
        self._mav.robust_parsing = True
        self._stop = threading.Event()
        self._thread = None

    # -- transports -------------------------------------------------------------------
    @classmethod
    def ardupilot(cls, sysid, home, port, alive=lambda: True, timeout_s=60.0) -> "Judge":
        """Connect to ArduPilot's SERIAL1 once it listens (after gcs has connected)."""
        judge = cls(sysid, home)

        def connect():
            wait_listening(port, timeout_s, alive)
            sock = socket.create_connection(("127.0.0.1", port), timeout=5)
            sock.settimeout(0.2)
            for stream, hz in ((M.MAV_DATA_STREAM_POSITION, RATE_HZ),
                               (M.MAV_DATA_STREAM_EXTENDED_STATUS, 2)):
                ask = judge._mav.request_data_stream_encode(sysid, 1, stream, hz, 1)
                sock.sendall(ask.pack(judge._mav))
            judge._send = sock.sendall
            return sock

        judge._start(lambda: judge._run_tcp(connect))
        return judge

    @classmethod
    def px4(cls, sysid, home, listen_port, px4_port) -> "Judge":
        """Listen where PX4's onboard link sends (bound before PX4 starts)."""
        judge = cls(sysid, home)
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        sock.bind(("127.0.0.1", listen_port))
        sock.settimeout(0.2)
        judge._start(lambda: judge._run_udp(sock, ("127.0.0.1", px4_port)))
        return judge

    def command(self, command: int, *params) -> None:
        """Send COMMAND_LONG ``command`` to the autopilot on this link."""
        self._out(self._mav.command_long_encode(self.sysid, 1, command, 0,
                                                *(list(params) + [0.0] * 7)[:7]))

    def set_param(self, name: str, value: float, integer: bool = False) -> None:
        """Set the autopilot's parameter ``name`` on this link (never the ground
        station's: what the test does to the vehicle, the ground station sees only
        in what the vehicle does). ``integer``: an INT32 parameter, sent bytewise as
        PX4 takes it (ArduPilot takes every value as a float)."""
        kind, wire = M.MAV_PARAM_TYPE_REAL32, float(value)
        if integer:
            kind = M.MAV_PARAM_TYPE_INT32
            wire = struct.unpack("<f", struct.pack("<i", int(value)))[0]
        self._out(self._mav.param_set_encode(self.sysid, 1, name.encode(), wire, kind))

    def _out(self, msg, timeout_s: float = 60.0) -> None:
        """Send ``msg``, once the link is connected (ArduPilot's second port opens only
        after the ground station has connected to the first)."""
        end = time.monotonic() + timeout_s
        while self._send is None:
            if time.monotonic() > end:
                raise RuntimeError(f"vehicle {self.sysid}: the judge's link is not connected")
            time.sleep(0.05)
        self._send(msg.pack(self._mav))

    def _start(self, target) -> None:
        self._thread = threading.Thread(target=target, daemon=True,
                                        name=f"judge-{self.sysid}")
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5)

    def _run_tcp(self, connect) -> None:
        """Read until the link closes; connected to again while the process lives
        (a reboot closes its ports, and opens them again)."""
        while not self._stop.is_set():
            try:
                sock = connect()
            except RuntimeError:
                return                                      # the process is gone
            except OSError:                                 # refused: a reboot under way
                time.sleep(0.2)
                continue
            with sock:
                self._read_tcp(sock)

    def _received(self, sock):
        """What ``sock`` receives, until the judge stops or the link fails or closes."""
        while not self._stop.is_set():
            try:
                data = sock.recv(65536)
            except socket.timeout:
                continue
            except OSError:
                return
            if not data:
                return
            yield data

    def _read_tcp(self, sock) -> None:
        rest = b""
        for data in self._received(sock):
            found, rest = frames(rest + data)
            self._keep(found)

    def _run_udp(self, sock, px4) -> None:
        asked = False
        self._send = lambda data: sock.sendto(data, px4)
        with sock:
            for data in self._received(sock):
                if not asked:                               # 10 Hz is plenty
                    ask = self._mav.command_long_encode(
                        self.sysid, 1, M.MAV_CMD_SET_MESSAGE_INTERVAL, 0, POSITION,
                        1e6 / RATE_HZ, 0, 0, 0, 0, 0)
                    sock.sendto(ask.pack(self._mav), px4)
                    asked = True
                self._keep(frames(data)[0])

    def _keep(self, found) -> None:
        now = time.time()
        for msgid, sysid, frame in found:
            if msgid not in WANTED or sysid != self.sysid:
                continue
            for msg in self._mav.parse_buffer(frame) or []:
                kind = msg.get_type()
                if kind == "GLOBAL_POSITION_INT":
                    if msg.lat or msg.lon:                  # 0, 0: no EKF origin yet
                        self.samples.append((now, msg.lat * 1e-7, msg.lon * 1e-7,
                                             msg.alt * 1e-3))
                        self.clock.append((now, msg.time_boot_ms * 1e-3))
                elif kind == "HEARTBEAT":
                    if msg.autopilot != M.MAV_AUTOPILOT_INVALID and \
                            (not self.modes or self.modes[-1][1] != msg.custom_mode):
                        self.modes.append((now, msg.custom_mode))
                elif kind == "SYS_STATUS":
                    if msg.battery_remaining >= 0:
                        self.battery.append((now, msg.battery_remaining))
                elif kind == "CAMERA_FEEDBACK":
                    self.shots.append((msg.lat * 1e-7, msg.lng * 1e-7, msg.alt_msl))
                elif kind == "CAMERA_IMAGE_CAPTURED":
                    self.shots.append((msg.lat * 1e-7, msg.lon * 1e-7, msg.alt * 1e-3))

    def track(self) -> tuple:
        """(t, lat, lon, alt, shots, home), as the fixtures' ``tracks()`` give them."""
        rows = np.array(self.samples, float).reshape(-1, 4)
        return (rows[:, 0], rows[:, 1], rows[:, 2], rows[:, 3], list(self.shots), self.home)


def closest_airborne(tracks, airborne_m=1.0, near=None) -> tuple:
    """(least distance m, (sysid, sysid), wall t) of two vehicles while both are more
    than ``airborne_m`` above their homes (and, given ``near`` = (lat, lon, radius
    m), both less than radius from that point across the ground), from their
    recorded tracks ({sysid: (wall t, lat, lon, alt, ...,  home)}), on the times of
    either's samples (linear between them); (inf, None, None) if never two at once."""
    import itertools

    best = (np.inf, None, None)
    lat0 = next(iter(tracks.values()))[1][0] if tracks else 0.0
    k = np.cos(np.radians(lat0)) * 6371008.8 * np.pi / 180
    for (a, ta), (b, tb) in itertools.combinations(sorted(tracks.items()), 2):
        t = np.union1d(ta[0], tb[0])
        t = t[(t >= max(ta[0][0], tb[0][0])) & (t <= min(ta[0][-1], tb[0][-1]))]
        if not len(t):
            continue
        pa = np.column_stack([np.interp(t, ta[0], ta[2]) * k, np.interp(t, ta[0], ta[1]) *
                              6371008.8 * np.pi / 180, np.interp(t, ta[0], ta[3])])
        pb = np.column_stack([np.interp(t, tb[0], tb[2]) * k, np.interp(t, tb[0], tb[1]) *
                              6371008.8 * np.pi / 180, np.interp(t, tb[0], tb[3])])
        up = (pa[:, 2] > ta[-1][2] + airborne_m) & (pb[:, 2] > tb[-1][2] + airborne_m)
        if near is not None:
            at = np.array([near[1] * k, near[0] * 6371008.8 * np.pi / 180])
            up &= (np.hypot(*(pa[:, :2] - at).T) < near[2]) & \
                (np.hypot(*(pb[:, :2] - at).T) < near[2])
        if not up.any():
            continue
        d = np.linalg.norm(pa - pb, axis=1)
        i = int(np.argmin(np.where(up, d, np.inf)))
        if d[i] < best[0]:
            best = (float(d[i]), (a, b), float(t[i]))
    return best


def shared_column(tracks, base, radius, top) -> tuple:
    """(longest s, (sysid, sysid), wall t it began) that two vehicles were at once in
    the column above ``base`` (lat, lon): airborne (more than 1 m above their
    homes), within ``radius`` m of it across the ground and below ``top`` m AMSL,
    from their recorded tracks as `closest_airborne` reads them (on the times of
    either's samples, linear between them); (0.0, None, None) if never."""
    import itertools

    k = np.cos(np.radians(base[0])) * 6371008.8 * np.pi / 180
    best = (0.0, None, None)
    for (a, ta), (b, tb) in itertools.combinations(sorted(tracks.items()), 2):
        t = np.union1d(ta[0], tb[0])
        t = t[(t >= max(ta[0][0], tb[0][0])) & (t <= min(ta[0][-1], tb[0][-1]))]
        if len(t) < 2:
            continue
        inside = np.ones(len(t), bool)
        for tr in (ta, tb):
            lat, lon, alt = (np.interp(t, tr[0], tr[i]) for i in (1, 2, 3))
            across = np.hypot((lon - base[1]) * k, (lat - base[0]) * 6371008.8 * np.pi / 180)
            inside &= (alt > tr[-1][2] + 1.0) & (across < radius) & (alt < top)
        # stretches of consecutive samples both inside
        edges = np.flatnonzero(np.diff(np.r_[0, inside.astype(int), 0]))
        for i0, i1 in zip(edges[::2], edges[1::2]):
            span = t[i1 - 1] - t[i0]
            if best[1] is None or span > best[0]:
                best = (float(span), (a, b), float(t[i0]))
    return best
