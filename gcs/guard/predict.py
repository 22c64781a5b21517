"""What the separation guard predicts with: the airborne vehicles now on one
local frame (`Frame`), trajectories halted or standing, and the geometry of two
of them (`closest_ahead`, `parting`, `exits`)."""

import time

import numpy as np

from planner.fleet import Trajectory

#: metres a pair standing too close may close in by rounding and still be parting
PARTING_SLACK_M = 0.5


def closest_ahead(d0, dv, horizon):
    """(least distance, after how long) of two straight motions, offset d0 (m) and
    relative velocity dv (m/s), over [0, horizon] s."""
    vv = float(np.dot(dv, dv))
    u = 0.0 if vv <= 1e-12 else min(max(-float(np.dot(d0, dv)) / vv, 0.0), horizon)
    return float(np.linalg.norm(d0 + u * dv)), u


def parting(frame, ahead, a, b) -> bool:
    """Whether ``a`` and ``b`` never come closer than they stand now."""
    now = float(np.linalg.norm(frame.position(a) - frame.position(b)))
    return ahead[a].closest_approach(ahead[b])[0] >= now - PARTING_SLACK_M


def exits(occupied) -> dict:
    """{column index: when it leaves that column} of a trajectory in a column now."""
    return {c: float(st[0, 1]) for c, st in enumerate(occupied.stretches)
            if len(st) and st[0, 0] <= 1e-9}


def halted(trajectory, at_s, until_s) -> Trajectory:
    """``trajectory`` flown until ``at_s``, then standing where it is until ``until_s``."""
    t, p = trajectory.t, trajectory.xyz
    at_s = min(max(at_s, t[0]), t[-1])
    keep = t < at_s
    here = np.array([np.interp(at_s, t, p[:, k]) for k in range(3)])
    times = np.r_[t[keep], at_s, max(until_s, at_s + 1e-3)]
    points = np.vstack([p[keep], here, here])
    return Trajectory(times, points, np.ones(len(times) - 1, bool))


class Frame:
    """The airborne vehicles now, on one local frame (`common.geo.LocalFrame`: metres
    east, north, up), each reported position carried forward to now at its
    reported velocity."""

    def __init__(self, monitor, sysids, rate, local):
        self.local = local
        self.unheard = set()      # out of contact: placed where its plan has it
        mono = time.monotonic()
        ids, points, moved = [], [], []
        for sysid in sysids:
            s = monitor.links[sysid].state
            if s.lat is None or s.velocity is None or s.position_at is None:
                continue
            planned = monitor.planned_position(sysid)
            if planned is not None:     # out of contact, as planned: it flies its plan
                points.append(planned)
                moved.append(np.zeros(3))
                self.unheard.add(sysid)
            else:
                north, east, up = s.velocity
                points.append((s.lon, s.lat, s.alt_amsl))
                moved.append(np.array([east, north, up]) * (mono - s.position_at) * rate)
            ids.append(sysid)
        # one projection for all: each call lets go of the interpreter, and getting it
        # back behind the simulator's and the links' threads took a millisecond or more
        self._p = dict(zip(ids, self.project(points) + np.array(moved).reshape(-1, 3)))

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
