"""Departures: every vehicle sent on its way at its time on the fleet clock.

A departure is a takeoff ("launch": the firmware's start sequence) or a vehicle a
re-plan held flying on ("resume"). Each goes in a thread of its own when its time
comes; a takeoff waits while another vehicle is in its base column, and claims
the column from its arming until it is seen airborne. The fleet clock reads a
vehicle's planned takeoff time when it leaves the ground (t = 0: the first
takeoff). Parts that care when a vehicle lifts off (the battery watch) listen
through ``on_liftoff``.
"""

import math
import threading
from dataclasses import dataclass
from types import SimpleNamespace

from gcs import commands
from gcs.monitor import FLYING, LANDED, LOST, STARTING, distance_m
from gcs.retask import Retasker

from .options import FlightError

#: wall seconds a called-off start sequence is given to stop (its command in flight
#: answered or timed out)
CALL_OFF_WAIT_S = 10.0

@dataclass
class Departure:
    """A vehicle to send on its way at fleet time ``due``: "launch" (its takeoff) or
    "resume" (flying on after a re-plan held it)."""

    due: float
    kind: str
    route: object


class Departures:
    """The takeoffs and resumes of one flight (see the module doc)."""

    def __init__(self, state):
        self.state = state
        self.pending = {}         # sysid -> Departure: takeoffs and resumes yet to come
        self._running = {}        # sysid -> (thread, error, cancel) of departures under way
        self._resuming = set()    # of them, vehicles a re-plan held, flying on
        self._waiting_for = {}    # sysid -> the vehicle its base column waits for
        self._lifting = {}        # sysid -> launch point of the base column claimed for it
        self._column_lock = threading.Lock()
        self._lifted = []         # (sysid, launch begun, lifted off): monitor times
        self.latency_s = 0.0      # fleet s from a launch's first command to its liftoff
        self.on_liftoff = []      # [(sysid, route) -> None]: told as each takes off

    def __contains__(self, sysid) -> bool:
        return sysid in self.pending

    def __bool__(self) -> bool:
        return bool(self.pending)

    def launch_all(self) -> None:
        """Every vehicle not lost takes off at its route's planned time."""
        m = self.state.monitor
        for sysid, v in m.vehicles.items():
            if v.state != LOST:
                self.pending[sysid] = Departure(v.route.takeoff_s, "launch", v.route)

    def launch(self, sysid, due, route) -> None:
        """``sysid`` takes off on ``route`` at fleet time ``due`` (its next sortie)."""
        self.pending[sysid] = Departure(due, "launch", route)

    def depart(self, sysid, after_s, kind, route) -> None:
        """``sysid`` takes off (``kind`` "launch") or flies on ("resume") ``after_s``
        fleet seconds from now (a re-plan's schedule)."""
        self.pending[sysid] = Departure((self.state.clock.now() or 0.0) + after_s, kind, route)

    def call_off(self) -> None:
        """A re-plan decides who goes up: every departure yet to come is dropped (a
        next sortie uploaded, its takeoff time not yet come, stays down), and every
        start sequence under way is stopped."""
        m = self.state.monitor
        for sysid in list(self.pending):
            del self.pending[sysid]
            m.call_off(sysid)
        self._call_off_starts()

    def clear(self) -> None:
        self.pending.clear()

    def waiting_s(self, sysid):
        """Fleet seconds until a vehicle a re-plan holds flies on (0 while it is
        being sent on), None when it waits for no re-plan: the separation guard
        leaves such a vehicle to the re-plan's schedule."""
        if sysid in self._resuming:
            return 0.0
        d = self.pending.get(sysid)
        if d is None or d.kind != "resume":
            return None
        return max(0.0, d.due - (self.state.clock.now() or 0.0))

    def due(self) -> None:
        """Send the vehicles whose time has come, each in its own thread; a takeoff
        waits while another airborne vehicle is in its base column. A failure of a
        vehicle still heard from stops the flight."""
        m = self.state.monitor
        self._anchor_clock()
        now = self.state.clock.now()
        if now is None:     # the clock starts at the first takeoff: those go now, alone
            now = -math.inf if self._running else \
                min((d.due for d in self.pending.values()), default=0.0)
        for sysid, (thread, error, _) in list(self._running.items()):
            if thread.is_alive():
                continue
            del self._running[sysid]
            if error and m.vehicles[sysid].state != LOST:
                raise FlightError(f"start failed: {error[0]}")
        for sysid, d in list(self.pending.items()):
            if m.vehicles[sysid].state == LOST:
                del self.pending[sysid]
                continue
            early = self.latency_s if d.kind == "launch" else 0.0
            if d.due - early > now or sysid in self._running:
                continue
            if d.kind == "launch" and not self._column_clear(sysid, d.route):
                continue
            del self.pending[sysid]
            self._send(sysid, d)

    def _send(self, sysid, d) -> None:
        error, cancel = [], threading.Event()
        run = self._launch if d.kind == "launch" else self._resume
        if d.kind == "resume":
            self._resuming.add(sysid)

        def go(s=sysid, route=d.route):
            try:
                run(s, route, cancel)
            except commands.CommandError as exc:
                error.append(exc)
            finally:
                self._resuming.discard(s)
        thread = threading.Thread(target=go, daemon=True, name=f"depart-{sysid}")
        self._running[sysid] = (thread, error, cancel)
        thread.start()

    def _launch(self, sysid, route, cancel) -> None:
        m, options = self.state.monitor, self.state.options
        begun, lifted = m.now(), []

        def liftoff():
            if not lifted:          # sent up: from now a re-plan holds it in the air
                m.event(sysid, "taking off")
            lifted.append(True)
            self._lifted.append((sysid, begun, m.now()))
            for listener in self.on_liftoff:
                listener(sysid, route)
        m.set_state(sysid, STARTING)
        try:
            # the column is looked at again as it arms: one held on the ground (refused
            # arming, a late start) may find another vehicle launched into it meanwhile
            column = SimpleNamespace(claim=lambda: self._claim_column(sysid, route),
                                     release=lambda: self._lifting.pop(sysid, None))
            commands.start_mission(m.links[sysid], route.waypoints[0].alt_amsl,
                                   ready_timeout_s=options.ready_timeout_s,
                                   retries=options.protocol_retries,
                                   on_liftoff=liftoff, cancel=cancel, column=column)
        except commands.StartCancelled:
            self._lifting.pop(sysid, None)
            # sent up: the re-plan holds it where it is; never sent up: it stays down
            if not lifted:
                m.call_off(sysid)
            return
        except BaseException:
            self._lifting.pop(sysid, None)
            if not lifted:
                m.call_off(sysid)     # still down: not one a re-plan would hold in the air
            raise
        m.set_state(sysid, FLYING)  # its column is kept until it is seen airborne

    def _resume(self, sysid, route=None, cancel=None) -> None:
        Retasker.resume(self.state.monitor, sysid, self.state.options.protocol_retries)
        self.state.monitor.set_state(sysid, FLYING)

    def _call_off_starts(self) -> None:
        """Stop every start sequence under way (a re-plan takes the vehicles over) and
        wait for their threads, so nothing they send comes after the re-plan's hold."""
        for thread, _, cancel in self._running.values():
            cancel.set()
        for sysid, (thread, _, _) in list(self._running.items()):
            thread.join(CALL_OFF_WAIT_S)
            if not thread.is_alive():
                del self._running[sysid]

    def _anchor_clock(self) -> None:
        """The fleet clock reads a vehicle's planned takeoff time when it is seen
        leaving the ground (t = 0: the first takeoff), and each launch is begun as
        much earlier as the last one took from its first command to that moment
        (arming, the takeoff command: `latency_s`), so takeoffs keep the plan's
        spacing whatever the ground station's and the vehicles' own delays."""
        m, clock = self.state.monitor, self.state.clock
        while self._lifted:
            sysid, begun, lifted = self._lifted.pop(0)
            if not clock.started:
                clock.start(m.vehicles[sysid].route.takeoff_s + (m.now() - lifted))
            self.latency_s = (lifted - begun) * clock.rate()

    def _claim_column(self, sysid, route) -> bool:
        """`_column_clear`, and if so the column kept for ``sysid`` from its arming
        until it is seen airborne (then its position keeps it) or its arming is refused:
        two vehicles whose start sequences overlap (one whose arming was refused for a
        while) would otherwise both find the column clear while on the ground, arm
        together and climb it one above the other."""
        with self._column_lock:
            if not self._column_clear(sysid, route):
                return False
            self._lifting[sysid] = route.launch
            return True

    def _column_clear(self, sysid, route) -> bool:
        """No other airborne vehicle within the separation of the column above its
        base (from the ground to the separation above its takeoff top), and the
        column claimed by no other vehicle lifting off (`_claim_column`)."""
        m = self.state.monitor
        sep = self.state.separation_m
        launch = route.launch
        if sep <= 0 or launch is None:
            return True
        for other, base in list(self._lifting.items()):
            v = m.vehicles[other]
            if v.airborne or v.state in (LOST, LANDED):
                self._lifting.pop(other, None)      # where it is now speaks for it
            elif other != sysid and base is not None and \
                    distance_m(launch.lat, launch.lon, base.lat, base.lon) < sep:
                return self._wait_for(sysid, other)
        top = route.waypoints[0].alt_amsl + sep
        for other, v in m.vehicles.items():
            s = m.links[other].state
            if other == sysid or not v.airborne or v.state in (LOST, LANDED) or s.lat is None:
                continue
            h = distance_m(launch.lat, launch.lon, s.lat, s.lon)
            below = max(launch.alt_amsl - s.alt_amsl, 0.0, s.alt_amsl - top)
            if math.hypot(h, below) < sep:
                return self._wait_for(sysid, other)
        self._waiting_for.pop(sysid, None)
        return True

    def _wait_for(self, sysid, other) -> bool:
        """False, said once per vehicle waited for."""
        if self._waiting_for.get(sysid) != other:
            self._waiting_for[sysid] = other
            self.state.monitor.event(sysid, f"takeoff waits: vehicle {other} is in its base "
                                            "column")
        return False
