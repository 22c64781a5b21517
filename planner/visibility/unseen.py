"""Why ground in the area of operations is not a coverage target.

The targets S_c are the cells some reachable hidden viewpoint sees; the rest of
the area of operations is never photographed. A plan says how much that is and
why, cell by cell (`unseen_reasons`), so that "100 % covered" is never read as
"the whole area":

- ``NO_DATA``: no elevation there (a void, or next to one or to the DEM's edge);
- ``OUT_OF_RANGE``: farther than the sensor range from every reachable viewpoint;
- ``TERRAIN``: in range, but the terrain (or the off-nadir limit) hides it from
  every reachable viewpoint;
- ``UNREACHABLE``: a hidden point would see it, but no hidden flight from the
  launch points reaches such a point (another hidden region, or a leg that
  would be seen).
"""

import numpy as np
from scipy import ndimage

from .sets import compute_visibility
from .viewpoints import candidate_viewpoints

SEEN, OUT_OF_RANGE, TERRAIN, UNREACHABLE, NO_DATA = 0, 1, 2, 3, 4
OUTSIDE = 255  # not in the area of operations
#: code -> what a map legend and a summary say
REASONS = {OUT_OF_RANGE: "out of sensor range of every reachable hidden viewpoint",
           TERRAIN: "hidden by the terrain from every reachable viewpoint",
           UNREACHABLE: "seen only from hidden points no hidden flight reaches",
           NO_DATA: "no elevation data (void or DEM edge)"}
#: at most this many extra candidates are looked from for UNREACHABLE (a coarser
#: lattice beyond): their visibility costs about as much as the plan's own
MAX_OTHER_CANDIDATES = 20000


def unseen_reasons(surface, viewpoints, visibility, sensor, spacing_m, area=None) -> np.ndarray:
    """uint8 [rows, cols]: `SEEN` for targets, `OUTSIDE` for cells outside ``area``
    (the area of operations, a bool grid; None: the whole grid), else the reason
    the cell is not a target. ``viewpoints``, ``visibility``: the plan's
    (reachable) candidates and their sets; ``spacing_m``: their lattice spacing."""
    terrain = surface.terrain
    shape = terrain.shape
    inside = np.ones(shape, bool) if area is None else np.asarray(area, bool)
    target = np.zeros(shape, bool)
    target.flat[visibility.target_cells] = True
    out = np.where(inside, SEEN, OUTSIDE).astype(np.uint8)
    rest = inside & ~target
    if not rest.any():
        return out
    out[rest & ~terrain.solid] = NO_DATA
    rest &= terrain.solid
    near = _within(viewpoints, shape, sensor.sensor_range_m, terrain.cell_size)
    out[rest] = np.where(near[rest], TERRAIN, OUT_OF_RANGE)
    others = _seen_from_elsewhere(surface, viewpoints, sensor, spacing_m)
    out[rest & others] = UNREACHABLE
    return out


def _within(viewpoints, shape, range_m, cell) -> np.ndarray:
    """Cells within ``range_m`` (horizontally, centre to centre) of a viewpoint."""
    if not len(viewpoints):
        return np.zeros(shape, bool)
    free = np.ones(shape, bool)
    free[viewpoints.indices[:, 0], viewpoints.indices[:, 1]] = False
    return ndimage.distance_transform_edt(free, sampling=cell) <= range_m


def _seen_from_elsewhere(surface, viewpoints, sensor, spacing_m) -> np.ndarray:
    """Cells seen from a candidate of any flyable region that is not one of the
    plan's viewpoints (no hidden flight reaches it)."""
    shape = surface.terrain.shape
    taken = np.zeros(shape, bool)
    taken[viewpoints.indices[:, 0], viewpoints.indices[:, 1]] = True
    if not surface.flyable.any():
        return np.zeros(shape, bool)
    spacing = spacing_m
    while True:
        others = candidate_viewpoints(surface, spacing, None, sensor.sensor_range_m)
        others = others.subset(~taken[others.indices[:, 0], others.indices[:, 1]])
        if len(others) <= MAX_OTHER_CANDIDATES:
            break
        spacing *= 1.5
    seen = np.zeros(shape, bool)
    if len(others):
        seen.flat[compute_visibility(surface, others, sensor).target_cells] = True
    return seen


#: why a target (ground some reachable hidden viewpoint sees) is not planned as
#: asked: ``area_summary``'s ``unplanned``
UNPLANNED = {"battery": "seen as asked only from viewpoints beyond one battery",
             "fewer": "seen by fewer UAVs than k+1",
             "none": "seen by no UAV of the plan"}


def area_summary(cell_size, unseen, cells, counts, needed, short=None, few=()) -> dict:
    """The area accounting of a plan, km² and % of the area of operations: every
    cell of it is in exactly one of ``planned``, ``unplanned`` (`UNPLANNED`'s
    reasons, and ``few``'s) and ``unseen`` (`REASONS`), so that they add up to the
    whole area.

    ``unseen``: `unseen_reasons` (the area of operations is where it is not
    `OUTSIDE`); ``cells`` (flat ids of the target cells) and ``counts`` (distinct
    UAVs seeing each): the plan's coverage; ``needed``: distinct UAVs each target
    needs; ``short``: bool per target, the sightings it needs only viewpoints
    beyond one battery give (None: no battery); ``few``: [(reason, bool per
    target)], targets of ``short`` that are so because too few UAVs reach them on
    one battery (`planner.shortfall`), each said with its own reason. ``visible``:
    ground some reachable hidden viewpoint sees (the targets); ``planned``: ground
    the plan sees as often as required."""
    km2 = cell_size ** 2 / 1e6
    inside = unseen != OUTSIDE
    total = int(inside.sum())
    in_area = inside.ravel()[cells]
    counts = np.asarray(counts)
    done = counts >= needed
    short = np.zeros(len(counts), bool) if short is None else np.asarray(short, bool)
    thin = {why: ~done & np.asarray(mask, bool) for why, mask in few}
    far = short.copy()
    for mask in thin.values():
        far &= ~mask
    missed = {UNPLANNED["battery"]: ~done & far, **thin,
              UNPLANNED["fewer"]: ~done & ~short & (counts > 0),
              UNPLANNED["none"]: ~done & ~short & (counts == 0)}

    def part(n):
        return {"km2": round(n * km2, 3), "pct": round(100.0 * n / total, 2) if total else 0.0}

    return {"area_km2": round(total * km2, 3), "visible": part(int(in_area.sum())),
            "planned": part(int((in_area & done).sum())),
            "unplanned": {why: part(int((in_area & m).sum())) for why, m in missed.items()},
            "unseen": {REASONS[code]: part(int((unseen == code).sum())) for code in REASONS}}
