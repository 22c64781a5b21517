"""Relaying the fleet's MAVLink to QGroundControl, MAVProxy or a MAVLink router.

    forward = Forwarder(["udpout:127.0.0.1:14550"])      # QGroundControl's default port
    link = GroundLink.open(urls, forward=forward, ...)    # every vehicle message relayed
    ...
    link.close()                                          # closes the forwarder too

What ``gcs fly --forward URL`` does, as MAVProxy's ``--out``: every message a
vehicle of the fleet sends is written, byte for byte as it came (its system id,
sequence and signature kept), to every forward URL, so QGroundControl shows each
vehicle live: position, mode, mission progress. Messages a vehicle addresses to
this ground station (mission protocol answers, command acks) are not relayed:
they answer our requests, not the other station's, and a QGroundControl with the
same system id (255) would take them for its own.

The way back is closed by default: whatever the forwarded side sends (a second
station's commands, mode changes, mission uploads, parameter requests) is
counted and dropped, so it cannot fight the re-tasking. With
``forward_commands`` it is passed on as it came, to the vehicle it addresses
(to every vehicle when it addresses none), and the vehicles' answers to that
station go back to it. A signing vehicle accepts only what is signed with its
key: the forwarded station must sign its own messages.

URLs are those ``--connect`` takes (`gcs.link.parse_url`): ``udpout:HOST:PORT``
sends to a station listening there (QGroundControl listens on UDP 14550),
``udpin:HOST:PORT`` listens and answers whoever sends to it, ``tcp:HOST:PORT``
connects to a TCP server (mavlink-router, MAVProxy), a serial ``DEVICE,BAUD``
feeds a radio.
"""

import collections
import threading

from gcs.link import POLL_S, Connection, LinkError
from gcs.mavlink import GCS_SYSTEM_ID


class Forwarder:
    """The forwarded side of a `gcs.link.GroundLink`: relays out, filters in."""

    def __init__(self, urls, forward_commands: bool = False):
        self.urls = list(urls)
        self.forward_commands = bool(forward_commands)
        self.connections = []
        self.relayed = 0                                 # vehicle messages written out
        self.dropped = collections.Counter()             # message type -> dropped coming in
        self.passed = collections.Counter()              # message type -> passed in
        self._ground = None
        self._stop = threading.Event()
        self._threads = []
        self._lock = threading.Lock()
        try:
            for url in self.urls:
                self.connections.append(Connection(url))
        except LinkError:
            self.close()
            raise

    # -- out: the fleet's messages ------------------------------------------------------
    def relay(self, vehicle, msg) -> None:
        """Called by the link's reader threads for every message of a fleet vehicle."""
        if not self.forward_commands and getattr(msg, "target_system", 0) == GCS_SYSTEM_ID:
            return
        packet = bytes(msg.get_msgbuf())
        with self._lock:
            for conn in self.connections:
                conn.write(packet)
            self.relayed += 1

    # -- in: what the forwarded side sends ---------------------------------------------
    def start(self, ground) -> "Forwarder":
        """Read the forwarded side (`GroundLink.start` calls this)."""
        self._ground = ground
        for conn in self.connections:
            t = threading.Thread(target=self._reader, args=(conn,), daemon=True,
                                 name=f"mavlink-forward {conn.url}")
            t.start()
            self._threads.append(t)
        return self

    def _reader(self, conn) -> None:
        while not self._stop.is_set():
            for msg, _ in conn.read(POLL_S):
                self._incoming(msg)

    def _incoming(self, msg) -> None:
        kind = msg.get_type()
        if not self.forward_commands or self._ground is None:
            self.dropped[kind] += 1
            return
        vehicles = self._ground.vehicles
        target = getattr(msg, "target_system", 0)
        chosen = [vehicles[target]] if target in vehicles else \
            list(vehicles.values()) if target == 0 else []
        if not chosen:
            self.dropped[kind] += 1
            return
        packet = bytes(msg.get_msgbuf())
        routes = {(id(v.connection), v._route[1]): v._route for v in chosen}
        # counted before it goes: a vehicle's answer, relayed back on another thread,
        # once reached the station while this count still said nothing was passed
        self.passed[kind] += 1
        for conn, addr in routes.values():
            self._ground._write_raw(conn, packet, addr)

    # -- end ------------------------------------------------------------------------
    def summary(self) -> str:
        """One line: what went out and what came back."""
        text = f"forwarded {self.relayed} vehicle messages to {', '.join(self.urls)}"
        if self.forward_commands:
            text += f"; passed {sum(self.passed.values())} from there to the vehicles"
        if self.dropped:
            top = ", ".join(f"{k} x{n}" for k, n in self.dropped.most_common(4))
            text += (f"; dropped {sum(self.dropped.values())} from there ({top})"
                     + ("" if self.forward_commands else ": --forward-commands passes them"))
        return text

    def close(self) -> None:
        self._stop.set()
        for t in self._threads:
            t.join(timeout=2)
        self._threads = []
        for conn in self.connections:
            conn.close()


__all__ = ["Forwarder"]
