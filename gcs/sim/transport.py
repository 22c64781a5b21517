"""The sockets of a simulated vehicle, on the endpoints real SITL uses.

ArduPilot SITL serves MAVLink on a TCP port (5760 + 10*i) to one client at a
time and greets its first client with plain text; PX4 SITL binds UDP 18570 + i
and sends to the ground station at 127.0.0.1:14550, answering whoever spoke last.
Both are polled from the vehicle's own thread; nothing here blocks longer than
the poll timeout. `PtyLink` serves a vehicle on a pseudo-terminal instead: a
serial link, as over a telemetry radio.
"""

import os
import select
import socket
import time


class TcpServerLink:
    def __init__(self, port: int, host: str = "127.0.0.1", banner: bytes = b""):
        self._address = (host, port)
        self._listener = self._listen()
        self._client = None
        self._banner = banner
        self.port = port
        self.accepted = 0          # clients so far: a new one gets the streams at once

    def _listen(self) -> socket.socket:
        listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            listener.bind(self._address)
        except OSError:
            listener.close()
            raise
        listener.listen(1)
        listener.setblocking(False)
        return listener

    def power_off(self) -> None:
        """The autopilot powered down: its client dropped, its port closed."""
        self.close()
        self._listener = None

    def power_on(self) -> bool:
        """Serving the port again; False while it cannot be bound yet."""
        try:
            self._listener = self._listen()
        except OSError:
            return False
        return True

    @property
    def connected(self) -> bool:
        return self._client is not None

    def poll(self, timeout: float) -> list:
        """Wait up to `timeout` s; return the byte chunks that arrived."""
        sock = self._client or self._listener
        if sock is None:                 # powered down
            time.sleep(max(timeout, 0.0))
            return []
        ready, _, _ = select.select([sock], [], [], max(timeout, 0.0))
        if not ready:
            return []
        if sock is self._listener:
            self._accept()
            return []
        return self._read()

    def _accept(self) -> None:
        try:
            client, _ = self._listener.accept()
        except BlockingIOError:
            return
        client.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        client.setblocking(False)
        self._client = client
        self.accepted += 1
        if self._banner:       # only the first client ever sees it, as with SITL
            self.send(self._banner)
            self._banner = b""

    def _read(self) -> list:
        chunks = []
        while self._client is not None:
            try:
                data = self._client.recv(65536)
            except BlockingIOError:
                break
            except OSError:
                data = b""
            if not data:
                self._drop_client()
                break
            chunks.append(data)
        return chunks

    def send(self, data: bytes) -> None:
        if self._client is None:
            return
        try:
            self._client.send(data)     # a full buffer loses the packet, like a slow link
        except BlockingIOError:
            pass
        except OSError:
            self._drop_client()

    def _drop_client(self) -> None:
        self._client.close()
        self._client = None

    def close(self) -> None:
        if self._client is not None:
            self._drop_client()
        if self._listener is not None:
            self._listener.close()


class _KeepsItsLine:
    """A link that outlives the autopilot's power: a UDP port, a serial line."""

    def power_off(self) -> None:
        """The autopilot powered down: the line stays (a radio keeps its link)."""

    def power_on(self) -> bool:
        return True


class UdpLink(_KeepsItsLine):
    def __init__(self, port: int, target: tuple = ("127.0.0.1", 14550),
                 host: str = "127.0.0.1"):
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            self._sock.bind((host, port))
        except OSError:
            self._sock.close()
            raise
        self._sock.setblocking(False)
        self._peer = target
        self.port = port

    connected = True
    accepted = 0

    def poll(self, timeout: float) -> list:
        ready, _, _ = select.select([self._sock], [], [], max(timeout, 0.0))
        chunks = []
        while ready:
            try:
                data, addr = self._sock.recvfrom(65536)
            except (BlockingIOError, ConnectionRefusedError):
                break
            self._peer = addr
            chunks.append(data)
        return chunks

    def send(self, data: bytes) -> None:
        try:
            self._sock.sendto(data, self._peer)
        except OSError:       # nobody listening yet: UDP just loses it
            pass

    def close(self) -> None:
        self._sock.close()


class PtyLink(_KeepsItsLine):
    """A serial line: the vehicle holds the master side of a pseudo-terminal and a
    ground station opens its slave device as a serial port (``DEVICE,BAUD``, e.g.
    ``/dev/pts/5,57600``), as it would a telemetry radio or a USB cable."""

    connected = True
    accepted = 0

    def __init__(self):
        import tty

        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)        # no echo, no line editing: bytes pass as they are
        os.set_blocking(self._master, False)
        self.device = os.ttyname(self._slave)   # kept open: the master never reads EOF

    def poll(self, timeout: float) -> list:
        ready, _, _ = select.select([self._master], [], [], max(timeout, 0.0))
        chunks = []
        while ready:
            try:
                data = os.read(self._master, 65536)
            except (BlockingIOError, InterruptedError):
                break
            except OSError:              # closed under us
                break
            if not data:
                break
            chunks.append(data)
        return chunks

    def send(self, data: bytes) -> None:
        try:
            os.write(self._master, data)   # a full line buffer loses it, like a slow radio
        except OSError:
            pass

    def close(self) -> None:
        for fd in (self._master, self._slave):
            try:
                os.close(fd)
            except OSError:
                pass
