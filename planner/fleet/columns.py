"""Base columns: the airspace above a base, one vehicle in it at a time.

Vehicles sharing a base climb out of it and come down into it through one column.
Kept apart only by distance, a second vehicle could start its climb while the
first still climbs above it, the separation between them; in the air such a
stack closes up as soon as one is slower than planned (an arming delay, a long
spool-up, a climb into wind): on real ArduPilot SITL two copters met 4-6 m apart
at the top of a shared column. So a column is a resource: while one airborne
vehicle is in it, no other may be. A vehicle is *in* a column when it is within
``radius`` (the separation) of the base across the ground and below ``top`` (the
column's top, the first waypoint above the base, plus the separation): it has
left once it is a separation away sideways, or a separation above the top.

The planner's schedule keeps columns exclusive as it keeps distances
(`schedule`), the plan's proof checks it (`prove_separated`), and the flight
enforces it from what the vehicles report (a takeoff waits for its column, the
separation guard holds a vehicle about to descend into a column in use).
"""

import math
from dataclasses import dataclass

import numpy as np

#: metres within which two bases are one (a shared launch point, rounded)
SAME_BASE_M = 1.0


@dataclass(frozen=True)
class Column:
    """The column above a base at (x, y): within ``radius`` of it across the ground,
    below ``top`` m AMSL."""

    x: float
    y: float
    top: float
    radius: float

    def contains(self, across_m: float, alt_m: float) -> bool:
        """Whether a point ``across_m`` from the base across the ground, at ``alt_m``
        AMSL, is in the column."""
        return across_m < self.radius and alt_m < self.top


def base_columns(bases, separation_m: float) -> list:
    """One `Column` per distinct base; ``bases``: (x, y, column top m AMSL) of each
    use of a base (a takeoff's first waypoint, a landing's last), the highest top of
    a base kept. None without a separation to keep."""
    if separation_m <= 0:
        return []
    out = []
    for x, y, top in bases:
        for i, c in enumerate(out):
            if math.hypot(c.x - x, c.y - y) <= SAME_BASE_M:
                out[i] = Column(c.x, c.y, max(c.top, top + separation_m), c.radius)
                break
        else:
            out.append(Column(float(x), float(y), float(top) + separation_m,
                              float(separation_m)))
    return out


def profile_bases(profiles) -> list:
    """(x, y, column top) of every takeoff and landing of `Profile` s: the ground
    point and the hidden polyline's first (takeoff) or last (landing) vertex."""
    out = []
    for p in profiles:
        first, last = p.route
        if p.on_ground[0]:
            out.append((p.xyz[0, 0], p.xyz[0, 1], p.xyz[first, 2]))
        if p.on_ground[1]:
            out.append((p.xyz[-1, 0], p.xyz[-1, 1], p.xyz[last, 2]))
    return out


def occupancy(trajectory, column: Column) -> np.ndarray:
    """[k, 2] the stretches of time (start, end) in which ``trajectory`` is airborne
    in ``column``, in order, touching ones merged: exact on its linear segments."""
    t, p = trajectory.t, trajectory.xyz
    if len(t) < 2:
        return np.zeros((0, 2))
    a_, b_ = p[:-1], p[1:]
    h0 = a_[:, :2] - (column.x, column.y)
    dh = b_[:, :2] - a_[:, :2]
    lo, hi = _within_radius(h0, dh, column.radius)
    zlo, zhi = _below(a_[:, 2], b_[:, 2] - a_[:, 2], column.top)
    lo = np.maximum(np.maximum(lo, zlo), 0.0)
    hi = np.minimum(np.minimum(hi, zhi), 1.0)
    keep = (lo < hi) & trajectory.air
    span = t[1:] - t[:-1]
    start = t[:-1][keep] + lo[keep] * span[keep]
    end = t[:-1][keep] + hi[keep] * span[keep]
    return _merged(start, end)


def _within_radius(h0, dh, radius) -> tuple:
    """(lo, hi) of each segment's fraction s with |h0 + s dh| < radius (lo >= hi: none)."""
    a = (dh * dh).sum(axis=1)
    b = 2.0 * (h0 * dh).sum(axis=1)
    c = (h0 * h0).sum(axis=1) - radius * radius
    still = a <= 1e-12
    disc = np.where(still, 0.0, b * b - 4.0 * a * c)
    root = np.sqrt(np.maximum(disc, 0.0))
    safe = np.where(still, 1.0, 2.0 * a)
    lo = np.where(still, np.where(c < 0, -np.inf, np.inf), (-b - root) / safe)
    hi = np.where(still, np.where(c < 0, np.inf, -np.inf), (-b + root) / safe)
    missed = ~still & (disc <= 0)
    return np.where(missed, np.inf, lo), np.where(missed, -np.inf, hi)


def _below(z0, dz, top) -> tuple:
    """(lo, hi) of each segment's fraction s with z0 + s dz < top."""
    level = np.abs(dz) <= 1e-12
    cross = np.where(level, 0.0, (top - z0) / np.where(level, 1.0, dz))
    lo = np.where(level, np.where(z0 < top, -np.inf, np.inf), np.where(dz > 0, -np.inf, cross))
    hi = np.where(level, np.where(z0 < top, np.inf, -np.inf), np.where(dz > 0, cross, np.inf))
    return lo, hi


def _merged(start, end) -> np.ndarray:
    out = []
    for s, e in zip(start, end):
        if out and s <= out[-1][1] + 1e-9:
            out[-1][1] = max(out[-1][1], e)
        else:
            out.append([s, e])
    return np.array(out, float).reshape(-1, 2)


def shared(a: np.ndarray, b: np.ndarray) -> tuple:
    """(start, end) of the first stretch in which two occupancies (`occupancy`) of
    one column overlap; (inf, inf) if they never do."""
    i = j = 0
    while i < len(a) and j < len(b):
        start, end = max(a[i, 0], b[j, 0]), min(a[i, 1], b[j, 1])
        if start < end - 1e-9:
            return float(start), float(end)
        if a[i, 1] < b[j, 1]:
            i += 1
        else:
            j += 1
    return math.inf, math.inf


class Occupied:
    """A trajectory with its occupancy of every column, for the schedule's walk
    (a placed vehicle's stretches are found once, not at every wait tried)."""

    def __init__(self, trajectory, columns):
        self.trajectory = trajectory
        self.stretches = [occupancy(trajectory, c) for c in columns]

    def first_shared(self, other: "Occupied", shift: float = 0.0) -> tuple:
        """(start, end) of the first stretch in which this one, ``shift`` s later,
        and ``other`` are in one column at once; (inf, inf) if never."""
        best = (math.inf, math.inf)
        for mine, theirs in zip(self.stretches, other.stretches):
            if len(mine) and len(theirs):
                found = shared(mine + shift, theirs)
                if found[0] < best[0]:
                    best = found
        return best


def first_shared_column(trajectories, columns) -> tuple:
    """(i, j, column index, start s) of the first time two of ``trajectories`` are in
    one column at once; None if never."""
    occupied = [Occupied(t, columns) for t in trajectories]
    best = None
    for i in range(len(occupied)):
        for j in range(i + 1, len(occupied)):
            for c, (a, b) in enumerate(zip(occupied[i].stretches, occupied[j].stretches)):
                start, _ = shared(a, b)
                if math.isfinite(start) and (best is None or start < best[3]):
                    best = (i, j, c, start)
    return best
