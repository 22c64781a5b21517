"""The separation guard: keeps airborne vehicles apart when they drift from the plan.

A plan proves its vehicles separated on its own schedule; real ones drift from it
(wind, speed, a late takeoff). Each flight-loop step the guard predicts where
every airborne vehicle will be over the next `horizon` seconds of fleet time: from
its reported position (carried forward to now at its reported velocity) along the
rest of its route, at the planned speeds, stops and holds, down to its landing
(`planner.fleet.Profile`: what it flies, not a straight line that ignores its
turns); a held vehicle stays where it is. Where two predictions come closer than
the separation within the horizon (`Trajectory.first_conflict`, exact), the guard
holds one of them where it is, in its firmware's hold mode, on its proven leg, so
hidden: the one of lower priority (the plan's: the later placed on the fleet
clock; before it, a vehicle short of battery, which every second held costs),
unless standing there would still be in the other's way, then the other; both
only when neither alone clears it. A held vehicle flies on, highest priority
first, once its route from where it stands keeps clear of every other's
prediction (with `RESUME_FACTOR` of room) and no other stands that close now, or,
where one does (two held in one base column), its route never comes closer to it
than now (the lower one's descent): a pair that close and parting is no conflict.
A held vehicle in its base column with nothing left to photograph, only the
column's top before its landing (`lands_here`: a re-plan that brought it home as it
took off), is flown on by landing from where it stands: up to the top it would
climb through the one descending above it, each waiting on the other for good.

A vehicle a re-plan holds until its own time to fly on (`waiting`) is the re-plan's:
the guard never holds or resumes it (resumed early, it flew its new route ahead of
time, and its resume at that time then sent it back to the route's first item in a
straight line, through a hill), and predicts it standing until then.

Every hold and resume is an event, and `report` gives them with the closest
approach seen between each pair (from telemetry).
"""

import threading
import time

import numpy as np

from common.geo import LocalFrame
from gcs import commands
from planner.fleet import Profile, Trajectory
from planner.travel import TravelParams

#: fleet seconds of look-ahead, beyond the ground station's own reaction time
HORIZON_S = 8.0
#: wall seconds from a position report to the vehicle braking on a hold
LATENCY_S = 1.0
#: a held vehicle flies on only when predicted this many separations clear
RESUME_FACTOR = 1.2
#: metres a pair standing too close may close in by rounding and still be parting
PARTING_SLACK_M = 0.5
#: wall seconds a re-plan waits for a hold or resume under way
FORGET_WAIT_S = 15.0


def closest_ahead(d0, dv, horizon):
    """(least distance, after how long) of two straight motions, offset d0 (m) and
    relative velocity dv (m/s), over [0, horizon] s."""
    vv = float(np.dot(dv, dv))
    u = 0.0 if vv <= 1e-12 else min(max(-float(np.dot(d0, dv)) / vv, 0.0), horizon)
    return float(np.linalg.norm(d0 + u * dv)), u


class GuardFleet:
    """What the guard reads of a flight and asks of its vehicles (a flight's
    `gcs.flight.holds.Holds`; tests give their own)."""

    def airborne(self) -> list:
        """The system ids flying now."""
        return []

    def hold(self, sysid) -> None:
        """Hold ``sysid`` where it is (its firmware's hold mode)."""

    def resume(self, sysid) -> None:
        """Fly ``sysid`` on along its route."""

    def on_pad(self, sysid) -> bool:
        """Touched down at its base, not yet told landed."""
        return False

    def short(self, sysid) -> bool:
        """Short of battery: it goes before every other."""
        return False

    def waiting(self, sysid):
        """Fleet seconds until a re-plan flies it on, None if it waits for none."""
        return None

    def lands_here(self, sysid) -> bool:
        """It may land from where it is (`land`)."""
        return False

    def land(self, sysid) -> None:
        """Land it from where it is."""
        self.resume(sysid)


class SeparationGuard:
    """Holds and resumes vehicles of one flight (see the module doc).

    ``priority[sysid]``: 1 has right of way; ``clock``: the flight's
    `gcs.clock.FleetClock`; ``fleet``: the flight's `GuardFleet`; ``travel``: the
    plan's speeds (`TravelParams`) and ``stop_s`` per waypoint."""

    def __init__(self, monitor, separation_m, priority, clock, fleet: GuardFleet,
                 travel=TravelParams(), stop_s=0.0):
        self.monitor, self.separation_m = monitor, float(separation_m)
        self.priority = dict(priority)
        self.clock, self.fleet = clock, fleet
        self.travel, self.stop_s = travel, float(stop_s)
        self.held = {}            # sysid -> (since t_s, other sysid)
        self.landing = set()      # flown on by landing where they stand
        self.actions = []         # the report's records
        self.closest = {}         # (a, b) -> [distance m, t_s]
        self._busy = set()        # a command in flight for these

    @property
    def active(self) -> bool:
        return self.separation_m > 0

    def horizon(self) -> float:
        return HORIZON_S + self.clock.rate() * LATENCY_S

    def forget(self, wait_s: float = FORGET_WAIT_S) -> None:
        """A re-plan took over the held vehicles (it holds and resumes them itself):
        a hold or resume under way is waited for (up to ``wait_s``), so nothing it
        sends (a resume may upload the rest of a route) comes after the re-plan's."""
        end = time.monotonic() + wait_s
        while self._busy and time.monotonic() < end:
            time.sleep(0.05)
        for sysid, (since, other) in self.held.items():
            self._record("released by a re-plan", sysid, other, None, since)
        self.held, self.landing = {}, set()

    def hold(self, sysid, other) -> None:
        """Hold ``sysid`` now, for ``other``: flown on as any hold, once clear."""
        self._do(sysid, self.fleet.hold, "hold", other)

    def step(self) -> None:
        if not self.active:
            return
        frame = _Frame(self.monitor, self.fleet.airborne(), self.clock.rate())
        if not frame.here:
            return
        self._note_closest(frame)
        self.landing &= set(frame.here)
        horizon = self.horizon()
        ahead = {s: (frame.standing(s, horizon) if s in self.held else
                     self._route(frame, s, self.fleet.waiting(s) or 0.0, s in self.landing))
                 for s in frame.here}
        for a, b, begin in self._conflicts(frame, ahead, horizon, self.separation_m):
            self._separate(frame, ahead, a, b, begin, horizon)
        for sysid in sorted(self.held, key=self._rank):
            if sysid not in frame.here:
                continue
            land = self.fleet.lands_here(sysid)
            go = self._route(frame, sysid, land=land)
            if self._may_go(frame, ahead, sysid, go, horizon):
                ahead[sysid] = go
                if land:
                    self.landing.add(sysid)
                self._do(sysid, self.fleet.land if land else self.fleet.resume,
                         "land here" if land else "resume", other=self.held[sysid][1])

    # -- predictions -------------------------------------------------------------------
    def _rank(self, sysid):
        return not self.fleet.short(sysid), self.priority.get(sysid, 99), sysid

    def _fixed(self, sysid) -> bool:
        """Held by the guard, or by a re-plan until its time: not the guard's to move."""
        return sysid in self.held or self.fleet.waiting(sysid) is not None

    def _route(self, frame, sysid, wait_s=0.0, land=False) -> Trajectory:
        """Where ``sysid`` flies from now, after standing ``wait_s``: the rest of its
        route, its landing included (``land``: only its landing, from where it is)."""
        v = self.monitor.vehicles[sysid]
        rest = [] if land else [w for i, w in enumerate(v.route.waypoints) if i not in v.done]
        poly = frame.project([(w.lon, w.lat, w.alt_amsl) for w in rest])
        base = v.route.landing          # the base this flight lands at
        ground = None if base is None else \
            frame.project([(base.lon, base.lat, base.alt_amsl)])[0]
        if not len(poly):
            poly = frame.position(sysid)[None]
        profile = Profile.of_route(poly, self.travel, launch=ground, start=frame.position(sysid),
                                   stop_s=self.stop_s)
        holds = np.zeros(profile.n)
        holds[profile.route[0]:profile.route[0] + len(rest)] = [w.hold_s for w in rest]
        holds[0] += wait_s          # vertex 0: where it stands now
        return profile.timed(0.0, holds)

    @staticmethod
    def _conflicts(frame, ahead, horizon, distance) -> list:
        """(a, b, when) of every pair predicted closer than ``distance`` within the
        horizon, soonest first; a pair already that close is one only while it
        closes in (one leaving the other is what ends it)."""
        out = []
        ids = sorted(ahead)
        for i, a in enumerate(ids):
            for b in ids[i + 1:]:
                begin, _ = ahead[a].first_conflict(ahead[b], distance)
                if begin <= horizon and not (begin == 0.0 and _parting(frame, ahead, a, b)):
                    out.append((a, b, begin))
        return sorted(out, key=lambda c: c[2])

    def _separate(self, frame, ahead, a, b, begin, horizon) -> None:
        """Hold one of a conflicting pair: the lower priority, unless standing where it
        is would still be in the other's way; both when neither alone will do."""
        if self._fixed(a) and self._fixed(b):
            return
        low, high = sorted((a, b), key=self._rank)[::-1]
        predicted = ahead[a].closest_approach(ahead[b])
        for target, other in ((low, high), (high, low)):
            if self._fixed(target):
                continue
            still = frame.standing(target, horizon)
            if ahead[other].first_conflict(still, self.separation_m)[0] > horizon:
                ahead[target] = still
                self._do(target, self.fleet.hold, "hold", other=other,
                         predicted=(predicted[0], begin))
                return
        for target, other in ((low, high), (high, low)):
            if not self._fixed(target):
                ahead[target] = frame.standing(target, horizon)
                self._do(target, self.fleet.hold, "hold", other=other,
                         predicted=(predicted[0], begin))

    def _may_go(self, frame, ahead, sysid, go, horizon) -> bool:
        """Whether ``sysid``'s route from here (``go``) keeps ``RESUME_FACTOR``
        separations clear of every other; from closer than that (two held in one
        base column) only a route that never comes closer than now, the lower one's
        descent."""
        room = self.separation_m * RESUME_FACTOR
        for other in frame.here:
            if other == sysid:
                continue
            if np.linalg.norm(frame.position(other) - frame.position(sysid)) < room:
                if not _parting(frame, {**ahead, sysid: go}, sysid, other):
                    return False
            elif go.first_conflict(ahead[other], room)[0] <= horizon:
                return False
        return True

    def _note_closest(self, frame) -> None:
        """The closest approach of each pair in the air: not counting one touched
        down on its base pad (a shared base is one point of the plan; the next
        vehicle's descent to it is the plan's, proven on its schedule)."""
        now = self.monitor.now()
        ids = sorted(s for s in frame.here if not self.fleet.on_pad(s))
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
            try:
                action(sysid)
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
            entry["predicted_m"], entry["in_s"] = round(predicted[0], 1), round(predicted[1], 1)
            text += (f" (vehicle {other} predicted {predicted[0]:.0f} m away in "
                     f"{predicted[1]:.0f} s)")
        if what != "hold":
            entry["held_s"] = round(now - since, 3)
        self.actions.append(entry)
        self.monitor.event(sysid, text, other=other)

    def report(self) -> dict:
        pairs = [{"vehicles": [a, b], "closest_m": d, "t_s": t}
                 for (a, b), (d, t) in sorted(self.closest.items())]
        return {"separation_m": self.separation_m, "actions": self.actions, "pairs": pairs,
                "closest_m": min((p["closest_m"] for p in pairs), default=None)}


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


def _parting(frame, ahead, a, b) -> bool:
    """Whether ``a`` and ``b`` never come closer than they stand now."""
    now = float(np.linalg.norm(frame.position(a) - frame.position(b)))
    return ahead[a].closest_approach(ahead[b])[0] >= now - PARTING_SLACK_M


class _Frame:
    """The airborne vehicles now, on one local frame (`common.geo.LocalFrame`: metres
    east, north, up), each reported position carried forward to now at its
    reported velocity."""

    def __init__(self, monitor, sysids, rate):
        self.monitor = monitor
        self._p, self.local = {}, None
        mono = time.monotonic()
        for sysid in sysids:
            s = monitor.links[sysid].state
            if s.lat is None or s.velocity is None or s.position_at is None:
                continue
            if self.local is None:
                self.local = LocalFrame(s.lat, s.lon)
            north, east, up = s.velocity
            p = self.project([(s.lon, s.lat, s.alt_amsl)])[0]
            self._p[sysid] = p + np.array([east, north, up]) * (mono - s.position_at) * rate

    @property
    def here(self) -> list:
        return list(self._p)

    def position(self, sysid) -> np.ndarray:
        return self._p[sysid]

    def project(self, points) -> np.ndarray:
        return self.local.project(points) if len(points) else np.zeros((0, 3))

    def standing(self, sysid, horizon) -> Trajectory:
        """Held where it is for the horizon."""
        p = self._p[sysid]
        return Trajectory(np.array([0.0, max(horizon, 1e-3)]), np.array([p, p]),
                          np.ones(1, bool))
