"""A radio between the ground station and each real SITL autopilot: the link is cut
both ways while the autopilot, by its own reported position, is out of the plan's
radio line of sight.

Real SITL has no radio: every byte reaches the ground station whatever the
terrain between. `Relay` stands where the radio would be. It passes each
vehicle's bytes on, and drops them (both ways) while the position that
autopilot reports of itself on its second link (the `judge.Judge`, which gcs
never sees) is out of contact of the plan's antennas, by the plan's own radio
model on the plan's terrain (`planner.link.contact_at`, the built-in
simulator's radio too). What the ground station then hears is what a telemetry
radio on that terrain would carry; what the vehicle flies through a silence is
its own doing.

- ArduPilot (TCP): the relay listens on a port of its own per vehicle; when the
  ground station connects, it connects to SITL's first port and pumps both ways.
  Bytes are dropped where they stand, as a radio drops them: a frame cut in two
  fails its checksum and the parsers find the next one.
- PX4 (UDP): the relay takes PX4's ground-station port (14550: each instance i
  sends there from 18570 + i), and passes each instance's datagrams on to the
  ground station from a socket of that instance's own, so that the ground
  station's answers come back to the right one.

Each cut and each return of a vehicle's link is kept (`Relay.cuts`) on the wall
clock: the silences the flight met, judged outside the ground station.
"""

import socket
import threading
import time

#: wall s between two looks at each vehicle's reported position
LOOK_S = 0.05
#: PX4 SITL instance i sends its ground-station link from this port + i
PX4_GCS_LOCAL = 18570


class Relay:
    """Cuts each vehicle's link while ``heard(lat, lon, alt AMSL)`` is False for the
    latest position its judge recorded (heard until the judge has one: on its
    pad)."""

    def __init__(self, judges: dict, heard):
        self.judges, self.heard = judges, heard
        self.cut = {sysid: False for sysid in judges}
        self.forced = {sysid: 0.0 for sysid in judges}   # cut by hand until (time.time())
        self.cuts = {sysid: [] for sysid in judges}     # [(wall t cut, wall t back or None)]
        self._stop = threading.Event()
        self._threads = []
        self._sockets = []
        self._spawn(self._look)

    # -- the radio ---------------------------------------------------------------------
    def _look(self) -> None:
        while not self._stop.wait(LOOK_S):
            for sysid, judge in self.judges.items():
                if not judge.samples:
                    continue
                _, lat, lon, alt = judge.samples[-1]
                cut = not self.heard(lat, lon, alt)
                if cut != self.cut[sysid]:
                    now = time.time()
                    if cut:
                        self.cuts[sysid].append((now, None))
                    else:
                        self.cuts[sysid][-1] = (self.cuts[sysid][-1][0], now)
                    self.cut[sysid] = cut

    @property
    def stopped(self) -> bool:
        return self._stop.is_set()

    def _passes(self, sysid: int) -> bool:
        return not self.cut[sysid] and time.time() >= self.forced[sysid]

    def cut_for(self, sysid: int, seconds: float) -> None:
        """Cut ``sysid``'s link both ways for ``seconds`` (wall), wherever it is: a
        radio that fails where the plan predicts contact."""
        self.forced[sysid] = time.time() + seconds

    # -- ArduPilot: TCP ----------------------------------------------------------------
    def tcp(self, sysid: int, upstream_port: int) -> int:
        """Listen for the ground station on a free local port for ``sysid``, whose
        SITL listens on ``upstream_port``; returns the relay's port."""
        server = socket.create_server(("127.0.0.1", 0))
        server.settimeout(0.2)
        self._sockets.append(server)
        self._spawn(self._serve_tcp, sysid, server, upstream_port)
        return server.getsockname()[1]

    def _serve_tcp(self, sysid, server, upstream_port) -> None:
        """One ground-station connection at a time, each to SITL afresh (a reboot
        closes SITL's port: the ground station connects again)."""
        while not self._stop.is_set():
            try:
                gcs, _ = server.accept()
            except socket.timeout:
                continue
            except OSError:
                return
            try:
                sitl = socket.create_connection(("127.0.0.1", upstream_port), timeout=5)
            except OSError:
                gcs.close()
                continue
            for a, b in ((gcs, sitl), (sitl, gcs)):
                a.settimeout(0.2)
            done = threading.Event()
            self._spawn(self._pump, sysid, gcs, sitl, done)
            self._pump(sysid, sitl, gcs, done)
            for s in (gcs, sitl):
                s.close()

    def _pump(self, sysid, src, dst, done) -> None:
        while not (self._stop.is_set() or done.is_set()):
            try:
                data = src.recv(65536)
            except socket.timeout:
                continue
            except OSError:
                break
            if not data:
                break
            if self._passes(sysid):
                try:
                    dst.sendall(data)
                except OSError:
                    break
        done.set()

    # -- PX4: UDP ----------------------------------------------------------------------
    def udp(self, vehicle_port: int, gcs_port: int) -> None:
        """Take PX4's ground-station port ``vehicle_port`` and pass every instance's
        datagrams to the ground station listening on ``gcs_port``."""
        side = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        side.bind(("0.0.0.0", vehicle_port))
        side.settimeout(0.2)
        self._sockets.append(side)
        self._spawn(self._serve_udp, side, ("127.0.0.1", gcs_port))

    def _serve_udp(self, side, gcs) -> None:
        own = {}                        # PX4's address -> the relay's socket for it
        for data, px4 in self._datagrams(side):
            sysid = px4[1] - PX4_GCS_LOCAL + 1
            if sysid not in self.cut:
                continue
            if px4 not in own:
                own[px4] = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
                own[px4].bind(("127.0.0.1", 0))
                own[px4].settimeout(0.2)
                self._sockets.append(own[px4])
                self._spawn(self._answers, sysid, own[px4], side, px4)
            if self._passes(sysid):
                own[px4].sendto(data, gcs)

    def _answers(self, sysid, sock, side, px4) -> None:
        """The ground station's datagrams to one PX4 instance, passed on to it."""
        for data, _ in self._datagrams(sock):
            if self._passes(sysid):
                side.sendto(data, px4)

    def _datagrams(self, sock):
        """(data, address) of what ``sock`` receives, until the relay stops."""
        while not self._stop.is_set():
            try:
                yield sock.recvfrom(65536)
            except socket.timeout:
                continue
            except OSError:
                return

    # -- life --------------------------------------------------------------------------
    def _spawn(self, target, *args) -> None:
        thread = threading.Thread(target=target, args=args, daemon=True, name="relay")
        thread.start()
        self._threads.append(thread)

    def stop(self) -> None:
        self._stop.set()
        for s in self._sockets:
            s.close()
        for thread in self._threads:
            thread.join(timeout=2)
        now = time.time()
        for sysid, cuts in self.cuts.items():
            if cuts and cuts[-1][1] is None:
                cuts[-1] = (cuts[-1][0], now)
