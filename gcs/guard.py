"""The separation guard: keeps airborne vehicles apart when they drift from the plan.

A plan proves its vehicles separated on its own schedule; real ones drift from it
(wind, speed, a late takeoff). Each flight-loop step the guard predicts every
airborne pair's closest approach over the next `horizon` seconds of fleet time
from telemetry (each position carried forward to now, then both moving straight
on at their reported velocities: the closed form of two linear motions) and,
before it would fall below the separation, holds the vehicle of lower priority
(the plan's: the later one placed on the fleet clock) where it is, in its
firmware's hold mode: on its proven leg, so hidden. If the pair still closes
(the one held sits in the other's way), the other is held too. A held vehicle
flies on once no other airborne vehicle is predicted within the separation of
it, moving toward its next waypoint at cruise speed, nor stands within it now.

Every hold and resume is an event, and `report` gives them with the closest
approach seen between each pair (from telemetry).
"""

import math
import threading
import time

import numpy as np

from gcs import commands

#: fleet seconds of look-ahead, beyond the ground station's own reaction time
HORIZON_S = 8.0
#: wall seconds from a position report to the vehicle braking on a hold
LATENCY_S = 1.0
#: a held vehicle flies on only when predicted this many separations clear
RESUME_FACTOR = 1.2
EARTH_R = 6371008.8


def closest_ahead(d0, dv, horizon):
    """(least distance, after how long) of two straight motions, offset d0 (m) and
    relative velocity dv (m/s), over [0, horizon] s."""
    vv = float(np.dot(dv, dv))
    u = 0.0 if vv <= 1e-12 else min(max(-float(np.dot(d0, dv)) / vv, 0.0), horizon)
    return float(np.linalg.norm(d0 + u * dv)), u


class SeparationGuard:
    """Holds and resumes vehicles of one flight (see the module doc).

    ``airborne()``: the system ids flying now; ``priority[sysid]``: 1 has right of
    way; ``clock``: the flight's `gcs.clock.FleetClock`; ``hold(sysid)`` /
    ``resume(sysid)``: what holding means for the flight (mode and state)."""

    def __init__(self, monitor, separation_m, priority, clock, airborne, hold, resume,
                 speed_mps=12.0):
        self.monitor, self.separation_m = monitor, float(separation_m)
        self.priority = dict(priority)
        self.clock, self.airborne = clock, airborne
        self._hold, self._resume = hold, resume
        self.speed_mps = float(speed_mps)
        self.held = {}            # sysid -> (since t_s, other sysid)
        self.actions = []         # the report's records
        self.closest = {}         # (a, b) -> [distance m, t_s]
        self._busy = set()        # a command in flight for these

    @property
    def active(self) -> bool:
        return self.separation_m > 0

    def horizon(self) -> float:
        return HORIZON_S + self.clock.rate() * LATENCY_S

    def forget(self) -> None:
        """A re-plan took over the held vehicles (it holds and resumes them itself)."""
        for sysid, (since, other) in self.held.items():
            self._record("released by a re-plan", sysid, other, None, since)
        self.held = {}

    def step(self) -> None:
        if not self.active:
            return
        now = self.monitor.now()
        states = self._states()
        self._note_closest(states, now)
        horizon = self.horizon()
        for (a, b), (d, when) in self._predictions(states, horizon).items():
            if d >= self.separation_m:
                continue
            low, high = sorted((a, b), key=lambda s: (self.priority.get(s, 99), s))[::-1]
            target = low if low not in self.held else high
            if target not in self.held:
                self._do(target, self._hold, now, "hold", other=high if target == low else low,
                         predicted=(d, when))
        for sysid in list(self.held):
            if sysid in states and self._clear(sysid, states, horizon):
                self._do(sysid, self._resume, now, "resume", other=self.held[sysid][1])

    # -- telemetry -------------------------------------------------------------------
    def _states(self) -> dict:
        """sysid -> (position m, velocity m/s) now, on a local flat frame."""
        out = {}
        rate = self.clock.rate()
        mono = time.monotonic()
        ids = self.airborne()
        lat0 = None
        for sysid in ids:
            s = self.monitor.links[sysid].state
            if s.lat is None or s.velocity is None or s.position_at is None:
                continue
            lat0 = s.lat if lat0 is None else lat0
            k = math.cos(math.radians(lat0))
            p = np.array([math.radians(s.lon) * EARTH_R * k, math.radians(s.lat) * EARTH_R,
                          s.alt_amsl])
            north, east, up = s.velocity
            v = np.array([east, north, up])
            if sysid in self.held:
                v = np.zeros(3)          # braking to a stop where it was told to
            out[sysid] = (p + v * (mono - s.position_at) * rate, v)
        return out

    def _predictions(self, states, horizon) -> dict:
        out = {}
        ids = sorted(states)
        for i, a in enumerate(ids):
            for b in ids[i + 1:]:
                (pa, va), (pb, vb) = states[a], states[b]
                out[a, b] = closest_ahead(pb - pa, vb - va, horizon)
        return out

    def _clear(self, sysid, states, horizon) -> bool:
        """Whether ``sysid``, flying on toward its next waypoint, keeps clear."""
        p, _ = states[sysid]
        v = self._onward(sysid, p)
        for other, (q, w) in states.items():
            if other == sysid:
                continue
            if np.linalg.norm(q - p) < self.separation_m * RESUME_FACTOR:
                return False
            if closest_ahead(q - p, w - v, horizon)[0] < self.separation_m * RESUME_FACTOR:
                return False
        return True

    def _onward(self, sysid, p) -> np.ndarray:
        """Velocity toward the vehicle's next waypoint at cruise speed (zero if unknown)."""
        v = self.monitor.vehicles[sysid]
        ahead = [i for i in range(len(v.route.waypoints)) if i not in v.done]
        if not ahead:
            return np.zeros(3)
        w = v.route.waypoints[ahead[0]]
        s = self.monitor.links[sysid].state
        k = math.cos(math.radians(s.lat))
        lat0 = s.lat
        d = np.array([math.radians(w.lon - s.lon) * EARTH_R * k,
                      math.radians(w.lat - lat0) * EARTH_R, w.alt_amsl - s.alt_amsl])
        n = np.linalg.norm(d)
        return d / n * self.speed_mps if n > 1e-6 else np.zeros(3)

    def _note_closest(self, states, now) -> None:
        ids = sorted(states)
        for i, a in enumerate(ids):
            for b in ids[i + 1:]:
                d = float(np.linalg.norm(states[b][0] - states[a][0]))
                seen = self.closest.get((a, b))
                if seen is None or d < seen[0]:
                    self.closest[a, b] = [round(d, 2), round(now, 3)]

    # -- actions ---------------------------------------------------------------------
    def _do(self, sysid, action, now, what, other, predicted=None) -> None:
        if sysid in self._busy:
            return
        if what == "hold":
            self.held[sysid] = (now, other)
        else:
            since, _ = self.held.pop(sysid)
        self._record(what, sysid, other, predicted, self.held.get(sysid, (now,))[0]
                     if what == "hold" else since)
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
