"""Departures: every vehicle sent on its way at its time on the fleet clock.

A departure is a takeoff ("launch": the firmware's start sequence) or a vehicle a
re-plan held flying on ("resume"). Each goes in a thread of its own when its time
comes. Parts that care when a vehicle is sent up (the battery watch) listen
through ``on_liftoff``.

One vehicle in a base column at a time, as the plan schedules it
(`planner.fleet.columns`), enforced from what the vehicles report, not from the
clock of the commands: a takeoff waits while another airborne vehicle is in its
base's column (within the separation of the base across the ground, below the
column's top and the separation, at any height below: SITL's ground can lie
140 m under a base), and claims the column from its arming until it is seen
airborne; and while the separation guard predicts an airborne vehicle in the
way of its climb and route (`SeparationGuard.in_way_of_takeoff`: one flying over
the base, or down its column, soon). Takeoffs are timed on what the vehicles do:
the fleet clock reads a vehicle's planned takeoff time when it is seen leaving
the ground (t = 0: the first takeoff), and a vehicle seen leaving later than
planned (arming, a slow spool-up) puts every takeoff after it as much later, so
that the plan's spacing is kept (on real ArduPilot SITL a liftoff came 7 s of
flight after the one before instead of the planned 15, timed from the commands).
That slip stays with the takeoffs yet to be scheduled too (the next sorties of
vehicles down for their swap), and no takeoff goes before one planned earlier:
the plan's separation is proven in its order and spacing of takeoffs. Three
vehicles late back from their battery swaps once went in the order they were
ready, out of the plan's, and the guard held two of them for each other until
their batteries ran out.
"""

import collections
import math
import threading
from dataclasses import dataclass
from types import SimpleNamespace

from common.geo import LocalFrame
from gcs import commands
from gcs.monitor import FLYING, LANDED, LOST, STARTING, STRANDED
from gcs.retask import Retasker
from planner.fleet import base_columns

from .options import FlightError

#: wall seconds a called-off start sequence is given to stop (its command in flight
#: answered or timed out)
CALL_OFF_WAIT_S = 10.0
#: fleet seconds a liftoff may come after its planned time before the takeoffs after
#: it are put later (the clock's own reading of a report is no finer)
SLIP_S = 1.0
#: the recent launches whose latency is kept (`Departures.latency_s`)
KEPT_LATENCIES = 8


def flight_bases(plan) -> list:
    """(lat, lon, column top m AMSL) of every takeoff and landing of ``plan``: each
    sortie's launch point under its first waypoint, and where it lands under its
    last (the separation guard's and the departures' base columns)."""
    out = []
    for v in plan.vehicles:
        for part in v.sortie_routes() if v.waypoints else []:
            if part.launch is not None:
                out.append((part.launch.lat, part.launch.lon, part.waypoints[0].alt_amsl))
            if part.landing is not None:
                out.append((part.landing.lat, part.landing.lon, part.waypoints[-1].alt_amsl))
    return out


@dataclass
class Departure:
    """A vehicle to send on its way at fleet time ``due``: "launch" (its takeoff) or
    "resume" (flying on after a re-plan held it)."""

    due: float
    kind: str
    route: object
    planned: float = None     # its time on the plan's clock, no slip added (`due` at first)

    def __post_init__(self):
        if self.planned is None:
            self.planned = self.due


class Departures:
    """The takeoffs and resumes of one flight (see the module doc)."""

    def __init__(self, state):
        self.state = state
        self.pending = {}         # sysid -> Departure: takeoffs and resumes yet to come
        self._running = {}        # sysid -> (thread, error, cancel) of departures under way
        self._resuming = set()    # of them, vehicles a re-plan held, flying on
        self._waiting_for = {}    # sysid -> (the vehicle its takeoff waits for, why)
        self._lifting = {}        # sysid -> launch point of the base column claimed for it
        self._column_lock = threading.Lock()
        self._launched = {}       # sysid -> (monitor s begun, fleet s due, planned) not yet up
        self.slip_s = 0.0         # fleet s the takeoffs yet to come go after their plan's time
        self._latencies = collections.deque(maxlen=KEPT_LATENCIES)   # `latency_s`'s
        self.on_liftoff = []      # [(sysid, route) -> None]: told as each is sent up
        # (sysid, fleet s before it climbs) -> the airborne vehicle in the way of its
        # takeoff, or None (`SeparationGuard.in_way_of_takeoff`; None: no guard)
        self.in_way = None
        # sysid -> whether it waits for the operator's word on its battery swap
        # (`Batteries.swap_awaited`; never, without one)
        self.awaits_operator = lambda sysid: False
        self._replanned_at = -math.inf  # monitor s of the last re-plan's call-off
        self._frame, self._columns = None, None     # the plan's base columns, once

    def __contains__(self, sysid) -> bool:
        return sysid in self.pending

    def __bool__(self) -> bool:
        return bool(self.pending)

    @property
    def latency_s(self) -> float:
        """Fleet seconds the quickest of the recent launches took from its first
        command to its liftoff (arming, the takeoff command, the spool-up), 0 before
        any: each launch is begun that much before its time. The quickest, not the
        last: one that lifts off later than its time only puts the takeoffs after it
        later, one earlier comes closer to the one before it (at 100x a launch came
        0.5 wall s quicker than the one before, 50 s of flight, and climbed after
        the vehicle ahead on its path)."""
        return min(self._latencies, default=0.0)

    def launch_all(self) -> None:
        """Every vehicle not lost takes off at its route's planned time."""
        m = self.state.monitor
        for sysid, v in m.vehicles.items():
            if v.state != LOST:
                self.pending[sysid] = Departure(v.route.takeoff_s, "launch", v.route)

    def launch(self, sysid, due, route) -> None:
        """``sysid`` takes off on ``route`` at the plan's fleet time ``due`` (its next
        sortie), as late as the takeoffs before it were (`slip_s`)."""
        self.pending[sysid] = Departure(due + self.slip_s, "launch", route, planned=due)

    def depart(self, sysid, after_s, kind, route) -> None:
        """``sysid`` takes off (``kind`` "launch") or flies on ("resume") ``after_s``
        fleet seconds from now (a re-plan's schedule)."""
        self.pending[sysid] = Departure((self.state.clock.now() or 0.0) + after_s, kind, route)

    def call_off(self) -> None:
        """A re-plan decides who goes up: every departure yet to come is dropped (a
        next sortie uploaded, its takeoff time not yet come, stays down), and every
        start sequence under way is stopped; its schedule starts from now, no slip."""
        m = self.state.monitor
        self.slip_s, self._replanned_at = 0.0, m.now()
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
        if now is None:     # the clock starts at the first liftoff: those go now, alone
            now = -math.inf if self._running or self._launched else \
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
            if d.kind == "launch" and not (self._in_turn(sysid, d) and
                                           self._column_clear(sysid, d.route) and
                                           self._clear_of_traffic(sysid)):
                continue
            self._waiting_for.pop(sysid, None)
            del self.pending[sysid]
            self._send(sysid, d)

    def _send(self, sysid, d) -> None:
        error, cancel = [], threading.Event()
        run = self._launch if d.kind == "launch" else self._resume
        if d.kind == "resume":
            self._resuming.add(sysid)
        else:
            self._launched[sysid] = (self.state.monitor.now(), d.due, d.planned)

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
        lifted = []

        def liftoff():
            if not lifted:          # sent up: from now a re-plan holds it in the air
                m.event(sysid, "taking off")
            lifted.append(True)
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
                self._grounded(sysid)
            return
        except BaseException:
            self._lifting.pop(sysid, None)
            if not lifted:
                self._grounded(sysid)     # still down: not one a re-plan would hold in the air
            raise
        m.set_state(sysid, FLYING)  # its column is kept until it is seen airborne

    def _grounded(self, sysid) -> None:
        """Its launch stopped before it was sent up: it stays down, no liftoff to come."""
        self._launched.pop(sysid, None)
        self.state.monitor.call_off(sysid)

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
        """Each launch seen leaving the ground (`Monitor`'s ``lifted_at_s``): the fleet
        clock reads its planned takeoff time then if it has not started (t = 0: the
        first takeoff); one later than planned puts every takeoff to come as much
        later (`_slipped`); and the time each took from its first command to its
        liftoff is kept (`latency_s`)."""
        m, clock = self.state.monitor, self.state.clock
        for sysid, (begun, due, _) in list(self._launched.items()):
            v = m.vehicles[sysid]
            if v.state == LOST:
                self._launched.pop(sysid, None)     # (a failed start's thread pops too)
                continue
            if v.lifted_at_s is None or v.lifted_at_s < begun:
                continue
            self._launched.pop(sysid, None)
            rate = clock.rate()
            ago = (m.now() - v.lifted_at_s) * rate      # fleet s since it lifted off
            if not clock.started:
                clock.start(due + ago)
            self._latencies.append((v.lifted_at_s - begun) * rate)
            if begun >= self._replanned_at:     # late on a schedule a re-plan replaced
                self._slipped(sysid, clock.now() - ago - due)

    def _slipped(self, sysid, late_s) -> None:
        """``sysid`` left the ground ``late_s`` fleet seconds after its planned time:
        the takeoffs to come wait as much longer, keeping the plan's spacing."""
        later = [s for s, d in self.pending.items() if d.kind == "launch"]
        if late_s <= SLIP_S:
            return
        self.slip_s += late_s
        if not later:
            return
        for other in later:
            self.pending[other].due += late_s
        self.state.monitor.event(sysid, f"left the ground {late_s:.0f} s after its planned "
                                        f"takeoff: the takeoffs after it are as much later",
                                 late_s=round(late_s, 1), vehicles=sorted(later))

    def _in_turn(self, sysid, d) -> bool:
        """No other vehicle's takeoff planned before ``d`` is yet to come: pending, sent
        and not seen up, or the next sortie of one flying or down for its swap; but
        not one whose swap the operator has left unconfirmed past its time (a pack
        kept out would hold every takeoff after it for good)."""
        m, now = self.state.monitor, self.state.clock.now()
        for other, v in list(m.vehicles.items()):
            if other == sysid or v.state in (LOST, STRANDED):
                continue
            first, sent = self.pending.get(other), self._launched.get(other)
            parts = self.state.later.get(other)
            if first is not None:
                if first.kind != "launch":
                    continue                # a resume is in the air already
                planned = first.planned
            elif sent is not None:
                planned = sent[2]
            elif parts:
                offset, route = parts[0]
                planned = offset + route.takeoff_s
                if now is not None and planned + self.slip_s < now and \
                        self.awaits_operator(other):
                    continue
            else:
                continue                    # no takeoff of its own to come
            if planned < d.planned:
                return self._wait_for(sysid, other, "takes off before it in the plan")
        return True

    def _clear_of_traffic(self, sysid) -> bool:
        """No airborne vehicle predicted in the way of its climb and route (`in_way`)."""
        other = self.in_way(sysid, self.latency_s) if self.in_way is not None else None
        return other is None or self._wait_for(sysid, other, "is predicted in its way")

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
            self._waiting_for.pop(sysid, None)
            return True

    def _column_clear(self, sysid, route) -> bool:
        """No other airborne vehicle in the column above its base (`column`), and the
        column claimed by no other vehicle lifting off (`_claim_column`)."""
        m = self.state.monitor
        launch = route.launch
        column = self.column(launch) if launch is not None else None
        if column is None:
            return True
        for other, base in list(self._lifting.items()):
            v = m.vehicles[other]
            # seen up (or down, or lost): where it is now speaks for it; a claim of
            # a takeoff long gone (nobody looked since) once held the column against
            # the next sortie's, while the claimant waited for that one in turn
            if v.airborne or v.state in (LOST, LANDED) or \
                    other not in self._running and other not in self._launched:
                self._lifting.pop(other, None)
            elif other != sysid and base is not None and self.column(base) is column:
                return self._wait_for(sysid, other)
        for other, v in m.vehicles.items():
            s = m.links[other].state
            if other == sysid or not v.airborne or v.state in (LOST, LANDED) or s.lat is None:
                continue
            x, y = self._frame.to_local(s.lat, s.lon)
            if column.contains(math.hypot(x - column.x, y - column.y), s.alt_amsl):
                return self._wait_for(sysid, other)
        return True

    def column(self, point):
        """The base column (`planner.fleet.Column`) ``point`` (lat, lon) stands in, in
        the flight's local frame; None without a separation to keep."""
        if self._columns is None:
            bases = flight_bases(self.state.plan)
            self._frame = LocalFrame(bases[0][0], bases[0][1]) if bases else None
            self._columns = base_columns(
                [(*self._frame.to_local(lat, lon), top) for lat, lon, top in bases],
                self.state.separation_m) if bases else []
        if not self._columns:
            return None
        x, y = self._frame.to_local(point.lat, point.lon)
        return min(self._columns, key=lambda c: math.hypot(c.x - x, c.y - y))

    def _wait_for(self, sysid, other, why="is in its base column") -> bool:
        """False, said once per vehicle and reason waited for."""
        if self._waiting_for.get(sysid) != (other, why):
            self._waiting_for[sysid] = (other, why)
            self.state.monitor.event(sysid, f"takeoff waits: vehicle {other} {why}")
        return False
