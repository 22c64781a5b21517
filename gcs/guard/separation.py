"""The separation guard's loop: `SeparationGuard` (see the package doc)."""

import collections
import threading
import time

import numpy as np

from common.geo import LocalFrame
from gcs import commands
from planner.fleet import Profile, Trajectory, base_columns
from planner.fleet.columns import Occupied
from planner.travel import TravelParams

from .fleet import GuardFleet
from .predict import Frame, exits, halted, parting

#: fleet seconds of look-ahead, beyond the ground station's own reaction time
HORIZON_S = 8.0
#: wall seconds from a position report to the vehicle braking on a hold, before any
#: command's round trip has been measured
LATENCY_S = 1.0
#: a held vehicle flies on only when predicted this many separations clear
RESUME_FACTOR = 1.2
#: wall seconds a re-plan waits for a hold or resume under way
FORGET_WAIT_S = 15.0
#: the loops and commands whose wall times are kept (the longest is counted)
KEPT_TIMES = 32
#: a held vehicle flies on no sooner than this many of the guard's loops after its hold
MIN_HOLD_LOOPS = 2


class SeparationGuard:
    """Holds and resumes vehicles of one flight (see the package doc, `gcs.guard`).

    ``priority[sysid]``: 1 has right of way; ``clock``: the flight's
    `gcs.clock.FleetClock`; ``fleet``: the flight's `GuardFleet`; ``travel``: the
    plan's speeds (`TravelParams`) and ``stop_s`` per waypoint; ``bases``: (lat,
    lon, column top m AMSL) of every base the fleet takes off from or lands at,
    each a column one vehicle at a time (`planner.fleet.columns`)."""

    def __init__(self, monitor, separation_m, priority, clock, fleet: GuardFleet,
                 travel=TravelParams(), stop_s=0.0, bases=()):
        self.monitor, self.separation_m = monitor, float(separation_m)
        self.priority = dict(priority)
        self.clock, self.fleet = clock, fleet
        self.travel, self.stop_s = travel, float(stop_s)
        self.bases = list(bases)
        self.held = {}            # sysid -> (since t_s, other sysid)
        self.landing = set()      # flown on by landing where they stand
        self.actions = []         # the report's records
        self.closest = {}         # (a, b) -> [distance m, t_s]
        self._busy = set()        # a command in flight for these
        self._loops = collections.deque(maxlen=KEPT_TIMES)     # wall s between steps
        self._commands = collections.deque(maxlen=KEPT_TIMES)  # wall s a command took
        self._last_step = None
        self._cycle = ([], 0)     # held vehicles waiting on each other, loops seen
        self._local = None        # the local frame of the flight (`_frame`)
        self._routes = {}         # id(route) -> (route, its projected points, landing)
        self._base_columns = None  # the bases' columns in that frame (`_columns`)

    @property
    def active(self) -> bool:
        return self.separation_m > 0

    @property
    def loop_s(self) -> float:
        """The longest of the guard's recent loops, wall s (the flight loop's period
        at least): what it may take to see a position and act on it."""
        return max(self._loops, default=0.0)

    @property
    def command_s(self) -> float:
        """The longest recent hold or resume from sending to its answer, wall s."""
        return max(self._commands, default=0.0)

    def reaction_s(self) -> float:
        """Fleet seconds a vehicle flies on after the position the guard acts on:
        one loop and one command, at the vehicles' rate."""
        return self.clock.rate() * (self.loop_s + self.command_s)

    def latency_s(self) -> float:
        """Wall seconds from a position report to the vehicle braking on a hold: a
        report's way down and a command's way up are one round trip, the longest a
        vehicle's acknowledged commands took lately (`LATENCY_S` before any). A
        fixed second was 100 s of flight at 100x: every conflict was looked for two
        minutes ahead, and a hold for one lasted until the batteries ran low."""
        # copied whole (list() is one step of the interpreter): the link threads append
        trips = [t for link in list(self.monitor.links.values())
                 for t in list(getattr(link, "round_trips", ()))] + list(self._commands)
        return max(trips) if trips else LATENCY_S

    def horizon(self) -> float:
        return HORIZON_S + self.clock.rate() * (self.latency_s() + self.loop_s)

    def forget(self, wait_s: float = FORGET_WAIT_S) -> None:
        """A re-plan took over the held vehicles (it holds and resumes them itself):
        a hold or resume under way is waited for (up to ``wait_s``), so nothing it
        sends (a resume may upload the rest of a route) comes after the re-plan's."""
        end = time.monotonic() + wait_s
        while self._busy and time.monotonic() < end:
            time.sleep(0.05)
        for sysid, (since, other) in self.held.items():
            self._record("released by a re-plan", sysid, other, None, since)
        self.held, self.landing, self._cycle = {}, set(), ([], 0)
        self._last_step = None        # the re-plan's time is no loop of the guard's

    def hold(self, sysid, other) -> None:
        """Hold ``sysid`` now, for ``other``: flown on as any hold, once clear."""
        self._do(sysid, self.fleet.hold, "hold", other)

    def step(self) -> None:
        if not self.active:
            return
        now = time.monotonic()
        if self._last_step is not None:
            self._loops.append(now - self._last_step)
        self._last_step = now
        frame = Frame(self.monitor, self.fleet.airborne(), self.clock.rate(), self._frame())
        if not frame.here:
            return
        self._note_closest(frame)
        self.landing &= set(frame.here)
        horizon = self.horizon()
        columns = self._columns()
        ahead = self._ahead(frame, horizon, frame.here)
        for a, b, begin, column in self._conflicts(frame, ahead, horizon, columns):
            if self._fixed(a) and self._fixed(b) or \
                    self._clash(ahead[a], ahead[b], columns) > horizon:
                continue            # a hold for an earlier conflict settled this one
            if column and begin <= 0.0:
                self._leave_first(frame, ahead, a, b, columns, horizon)
            else:
                self._separate(frame, ahead, a, b, begin, horizon, columns, column)
        # a vehicle flies on only when clear for longer than a conflict is looked for
        # (and by more room): a resume is not undone by the next loop's look
        ahead_longer = RESUME_FACTOR * horizon + self.reaction_s()
        waits_on = {}
        for sysid in sorted(self.held, key=self._rank):
            if sysid not in ahead or not self._held_long_enough(sysid):
                continue
            land = self.fleet.lands_here(sysid)
            go = self._route(frame, sysid, land=land)
            waits_on[sysid] = self._in_way(frame, ahead, sysid, go, ahead_longer, columns)
            if waits_on[sysid] is None:
                # it leaves where it stands once the command has reached it
                ahead[sysid] = self._route(frame, sysid, self.reaction_s(), land=land)
                if land:
                    self.landing.add(sysid)
                self._do(sysid, self.fleet.land if land else self.fleet.resume,
                         "land here" if land else "resume", other=self.held[sysid][1])
        self._note_cycle(waits_on)

    def in_way_of_takeoff(self, sysid, wait_s=0.0):
        """The airborne vehicle in the way of ``sysid``'s takeoff from where it stands
        (its route climbing after ``wait_s`` fleet seconds), as of a held vehicle's
        resume (`_in_way`); None when it may go. The base column being clear now
        was not enough: a vehicle took off 30 s late from under one flying over its
        base, and the guard, which sees only those in the air, found them 3 m apart."""
        if not self.active:
            return None
        frame = Frame(self.monitor, [*self.fleet.airborne(), sysid], self.clock.rate(),
                       self._frame())
        if sysid not in frame.here:
            return None             # no position yet: the column rule alone
        horizon, columns = self.horizon(), self._columns()
        ahead = self._ahead(frame, horizon, [s for s in frame.here if s != sysid])
        go = self._route(frame, sysid, wait_s)
        # looked at until it is out of its base column, and as long after its climb
        # begins as a resume is: the launch's own latency (arming, the spool-up) was
        # 100 s of flight at 100x, and a look that short saw it only on its pad
        out = max(exits(Occupied(go, columns)).values(), default=0.0)
        until = max(out, wait_s + RESUME_FACTOR * horizon + self.reaction_s())
        return self._in_way(frame, ahead, sysid, go, until, columns)

    @property
    def deadlocked(self) -> list:
        """Held vehicles that have waited on each other for `MIN_HOLD_LOOPS` loops
        running (none will ever go first): the flight re-plans them."""
        cycle, loops = self._cycle
        return cycle if loops >= MIN_HOLD_LOOPS else []

    def _note_cycle(self, waits_on) -> None:
        """Follow each held vehicle to the one in its way, to a cycle of held ones."""
        found = []
        for start in sorted(waits_on):
            seen, s = [], start
            while s in waits_on and waits_on[s] is not None and s not in seen:
                seen.append(s)
                s = waits_on[s]
            if s in seen:
                found = sorted(seen[seen.index(s):])
                break
        cycle, loops = self._cycle
        self._cycle = (found, loops + 1 if found and found == cycle else int(bool(found)))

    # -- predictions -------------------------------------------------------------------
    def _rank(self, sysid):
        """Held first the higher: right of way to one short of battery, then to one
        at a predicted radio shadow (held in it, its link-loss failsafe would fly it
        home: a hold braked vehicle 1 of a simulated flight 1.4 s of flight short of a
        shadow, and 5 s into it SmartRTL took it home, its coverage left undone),
        then by priority."""
        return not self.fleet.short(sysid), not self.monitor.near_shadow(sysid), \
            self.priority.get(sysid, 99), sysid

    def _fixed(self, sysid) -> bool:
        """Held by the guard, by a re-plan until its time, out of contact (no command
        reaches it: it flies its plan), or flying a failsafe's return (a hold and resume
        would send it back to its mission): not the guard's to move."""
        return sysid in self.held or self.fleet.waiting(sysid) is not None or \
            self.monitor.planned_at(sysid) is not None or self.monitor.in_failsafe(sysid)

    def _held_long_enough(self, sysid) -> bool:
        """Held for `MIN_HOLD_LOOPS` of the guard's loops at least: a hold and its
        resume within one loop (both in 0.1 s once, at the top of a base column)
        acted on nothing the vehicles had done."""
        since, _ = self.held[sysid]
        return self.monitor.now() - since >= MIN_HOLD_LOOPS * self.loop_s

    def _route(self, frame, sysid, wait_s=0.0, land=False) -> Trajectory:
        """Where ``sysid`` flies from now, after standing ``wait_s``: the rest of its
        route, its landing included (``land``: only its landing, from where it is)."""
        v = self.monitor.vehicles[sysid]
        silent_at = self.monitor.planned_at(sysid)    # out of contact: where its plan is
        rest = [] if land else [i for i, w in enumerate(v.route.waypoints) if i not in v.done
                                and (silent_at is None or w.t_s > silent_at)]
        route, ground = self._projected(v.route)
        poly = route[rest]
        if not len(poly):
            poly = frame.position(sysid)[None]
        profile = Profile.of_route(poly, self.travel, launch=ground, start=frame.position(sysid),
                                   stop_s=self.stop_s)
        holds = np.zeros(profile.n)
        holds[profile.route[0]:profile.route[0] + len(rest)] = \
            [v.route.waypoints[i].hold_s for i in rest]
        holds[0] += wait_s          # vertex 0: where it stands now
        return profile.timed(0.0, holds)

    def _ahead(self, frame, horizon, ids) -> dict:
        """{sysid: its predicted flight} of ``ids``: a held one standing, the others
        on their routes. One down on its pad (its landing not told yet) is in
        nobody's way; one held just above it is (and is flown on from there: left
        out, it hovered for good)."""
        return {s: (frame.standing(s, horizon) if s in self.held else
                    self._route(frame, s, self.fleet.waiting(s) or 0.0, s in self.landing))
                for s in ids if s in self.held or not self.fleet.on_pad(s)}

    def _frame(self) -> LocalFrame:
        """The guard's local frame, about its first base (or the first vehicle heard),
        kept for the flight: a frame made anew per loop cost as much as its use."""
        if self._local is None:
            at = self.bases[0][:2] if self.bases else next(
                ((s.lat, s.lon) for s in (self.monitor.links[i].state
                                          for i in self.monitor.links) if s.lat is not None),
                (0.0, 0.0))
            self._local = LocalFrame(*at)
        return self._local

    def _columns(self) -> list:
        """The bases' `Column` s in the guard's frame (made once: the bases stay)."""
        if self._base_columns is None:
            local = self._frame()
            self._base_columns = base_columns(
                [(*local.to_local(lat, lon), top) for lat, lon, top in self.bases],
                self.separation_m)
        return self._base_columns

    def _projected(self, route) -> tuple:
        """(route's waypoints [n, 3] in the guard's frame, its landing base's point or
        None), projected once per route."""
        if self._routes.get(id(route), (None,))[0] is not route:
            local, base = self._frame(), route.landing
            points = local.project([(w.lon, w.lat, w.alt_amsl) for w in route.waypoints])
            ground = None if base is None else \
                local.project([(base.lon, base.lat, base.alt_amsl)])[0]
            self._routes[id(route)] = (route, points.reshape(-1, 3), ground)
        return self._routes[id(route)][1:]

    def _stopping(self, frame, sysid, horizon) -> Trajectory:
        """``sysid`` held now: it flies on along its route for the guard's reaction
        time (`reaction_s`), then stands there."""
        route = self._route(frame, sysid, self.fleet.waiting(sysid) or 0.0,
                            sysid in self.landing)
        return halted(route, self.reaction_s(), horizon)

    def _conflicts(self, frame, ahead, horizon, columns) -> list:
        """(a, b, when, column) of every pair predicted closer than the separation,
        or in one base column (``column``), within the horizon, soonest first; a pair
        already that close is one only while it closes in (one leaving the other is
        what ends it)."""
        out = []
        ids = sorted(ahead)
        occupied = {s: Occupied(ahead[s], columns) for s in ids}
        for i, a in enumerate(ids):
            for b in ids[i + 1:]:
                begin, _ = ahead[a].first_conflict(ahead[b], self.separation_m)
                if begin <= horizon and not (begin == 0.0 and parting(frame, ahead, a, b)):
                    out.append((a, b, begin, False))
                shared, _ = occupied[a].first_shared(occupied[b])
                if shared <= horizon:
                    out.append((a, b, shared, True))
        return sorted(out, key=lambda c: c[2])

    def _clash(self, one, other, columns) -> float:
        """When trajectory ``one`` first comes closer than the separation to ``other``
        or shares a column with it (inf: never)."""
        begin, _ = one.first_conflict(other, self.separation_m)
        shared, _ = Occupied(one, columns).first_shared(Occupied(other, columns))
        return min(begin, shared)

    def _separate(self, frame, ahead, a, b, begin, horizon, columns, column=False) -> None:
        """Hold one of a conflicting pair: the lower priority, unless holding it (it
        flies on for the guard's reaction time first) would still be in the
        other's way; both when neither alone will do. ``column``: the two are
        predicted in one base column at ``begin``, not closer than the separation."""
        if self._fixed(a) and self._fixed(b):
            return
        low, high = sorted((a, b), key=self._rank)[::-1]
        predicted = (ahead[a].closest_approach(ahead[b])[0], begin, column)
        for target, other in ((low, high), (high, low)):
            if self._fixed(target):
                continue
            still = self._stopping(frame, target, horizon)
            if self._clash(ahead[other], still, columns) > horizon:
                ahead[target] = still
                self._do(target, self.fleet.hold, "hold", other=other, predicted=predicted)
                return
        for target, other in ((low, high), (high, low)):
            if not self._fixed(target):
                ahead[target] = self._stopping(frame, target, horizon)
                self._do(target, self.fleet.hold, "hold", other=other, predicted=predicted)

    def _leave_first(self, frame, ahead, a, b, columns, horizon) -> None:
        """Two in one base column now: the one whose route leaves it first (climbing
        out above, or landing below) goes; the other holds."""
        stay = self._stayer(frame, a, b, columns)
        if stay is None or self._fixed(stay):
            return
        other = b if stay == a else a
        ahead[stay] = self._stopping(frame, stay, horizon)
        self._do(stay, self.fleet.hold, "hold", other=other,
                 predicted=(float(np.linalg.norm(frame.position(a) - frame.position(b))), 0.0,
                            True))

    def _stayer(self, frame, a, b, columns):
        """Of two in one column, the one that leaves it later flying its route (None:
        they are in no column together)."""
        leave = {s: exits(Occupied(self._route(frame, s, land=s in self.landing), columns))
                 for s in (a, b)}
        shared = [c for c in range(len(columns)) if c in leave[a] and c in leave[b]]
        if not shared:
            return None
        c = shared[0]
        return a if leave[a][c] > leave[b][c] else b

    def _in_way(self, frame, ahead, sysid, go, horizon, columns):
        """The vehicle in the way of ``sysid``'s route from here (``go``), None when
        it may go: that route keeps ``RESUME_FACTOR`` separations clear of every
        other and shares no column with one within the horizon; from closer than
        that (two held in one base column) only a route that parts from the other
        standing where it is (not counting on the other's own motion: at the top of
        a column a copter lingers as it turns to its first leg); two in one column
        now, only the one that leaves it first."""
        room = self.separation_m * RESUME_FACTOR
        mine = Occupied(go, columns)
        for other in ahead:
            if other == sysid:
                continue
            if np.linalg.norm(frame.position(other) - frame.position(sysid)) < room:
                # the other where it stands, while it is in the air (one landing is not)
                still = frame.standing(other, min(horizon, ahead[other].end))
                if not parting(frame, {sysid: go, other: still}, sysid, other):
                    return other
            elif go.first_conflict(ahead[other], room)[0] <= horizon:
                return other
            shared, _ = mine.first_shared(Occupied(ahead[other], columns))
            if shared <= 0.0:
                if self._stayer(frame, sysid, other, columns) == sysid:
                    return other
            elif shared <= horizon:
                return other
        return None

    def _note_closest(self, frame) -> None:
        """The closest approach of each pair in the air, as reported: not counting one
        touched down on its base pad (a shared base is one point of the plan; the
        next vehicle's descent to it is the plan's, proven on its schedule), nor one
        out of contact (where its plan has it is no measurement: a vehicle shot down
        in its shadow was "flown" 1.8 m from one that passed the place later)."""
        now = self.monitor.now()
        ids = sorted(s for s in frame.here if not self.fleet.on_pad(s)
                     and s not in frame.unheard)
        for i, a in enumerate(ids):
            for b in ids[i + 1:]:
                d = float(np.linalg.norm(frame.position(a) - frame.position(b)))
                seen = self.closest.get((a, b))
                if seen is None or d < seen[0]:
                    self.closest[a, b] = [round(d, 2), round(now, 3)]

    # -- actions ---------------------------------------------------------------------
    def _do(self, sysid, action, what, other, predicted=None) -> None:
        if sysid in self._busy:
            return
        now = self.monitor.now()
        since = now
        if what == "hold":
            self.held[sysid] = (now, other)
        else:
            since, _ = self.held.pop(sysid)
        self._record(what, sysid, other, predicted, since)
        self._busy.add(sysid)

        def run():
            sent = time.monotonic()
            try:
                action(sysid)
                self._commands.append(time.monotonic() - sent)
            except commands.CommandError as exc:
                self.monitor.event(sysid, f"separation guard: {what} failed", error=str(exc))
            finally:
                self._busy.discard(sysid)
        threading.Thread(target=run, daemon=True, name=f"guard-{sysid}").start()

    def _record(self, what, sysid, other, predicted, since) -> None:
        now = self.monitor.now()
        entry = {"t_s": round(now, 3), "sysid": sysid, "action": what, "other": other}
        text = f"separation guard: {what}"
        if predicted is not None:
            d, when, column = predicted
            entry["predicted_m"], entry["in_s"] = round(d, 1), round(when, 1)
            if column:
                entry["column"] = True
                text += f" (vehicle {other} predicted in one base column with it in {when:.0f} s)"
            else:
                text += f" (vehicle {other} predicted {d:.0f} m away in {when:.0f} s)"
        if what != "hold":
            entry["held_s"] = round(now - since, 3)
        self.actions.append(entry)
        self.monitor.event(sysid, text, other=other)

    def report(self) -> dict:
        pairs = [{"vehicles": [a, b], "closest_m": d, "t_s": t}
                 for (a, b), (d, t) in sorted(self.closest.items())]
        return {"separation_m": self.separation_m, "actions": self.actions, "pairs": pairs,
                "closest_m": min((p["closest_m"] for p in pairs), default=None),
                "loop_s": round(self.loop_s, 3), "command_s": round(self.command_s, 3),
                "latency_s": round(self.latency_s(), 3)}


def hold_spans(actions, end) -> list:
    """[(sysid, (from, to))] flight seconds of each hold in the guard's ``actions``
    (`SeparationGuard.actions`, the report's ``separation.actions``), one still on
    ending at ``end``."""
    out, since = [], {}
    for a in actions:
        if a["action"] == "hold":
            since[a["sysid"]] = a["t_s"]
        elif a["sysid"] in since:
            out.append((a["sysid"], (since.pop(a["sysid"]), a["t_s"])))
    return out + [(s, (t, end)) for s, t in since.items()]
