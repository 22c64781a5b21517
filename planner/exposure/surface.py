"""The exposure surface E: where a UAV can fly without being seen.

Visibility model (shared with planner.exposure.los): the terrain surface is the bilinear
interpolation of cell centres; an outpost at (x, y) has its eye ``height_m``
above that surface; it sees a point P when P is within its range and the
straight segment from the eye to P does not pass below the terrain surface,
with GDAL's earth curvature and refraction (``curvature_coeff``). Visibility is
monotone in altitude, so each outpost has a lowest seen altitude per cell; E is
the minimum over outposts, capped at ``ground + ceiling_agl``. A cell is
flyable when ``E - hide_margin >= ground + clearance`` and the surface is known
all around it (`Terrain.solid`); the connected regions of flyable cells are
where the fleet flies. On a resampled DEM, sight lines are occluded by the
terrain's lower surface and the outposts' eyes and the clearance stand on its
upper surface (`planner.terrain.grid`), so E is safe against the source DEM too.

``compute_exposure`` uses a fast ring sweep (``lowest_seen``, alone) that is a
proven lower bound of the exact lowest seen altitude (the safe side; see
planner.exposure.kernels).
``is_hidden``, ``segment_hidden`` and ``segment_clear`` are exact or
conservative checks used to prove that a flown leg is hidden and clear.
"""

from dataclasses import dataclass, replace

import numba
import numpy as np
from scipy import ndimage

from . import kernels as k
from .los import DEFAULT_CURVATURE_COEFF


@dataclass(frozen=True)
class ExposureParams:
    ceiling_agl_m: float = 120.0  # never fly higher than this above the ground
    clearance_m: float = 30.0  # never fly lower than this above the ground
    hide_margin_m: float = 10.0  # fly this far below E
    curvature_coeff: float = DEFAULT_CURVATURE_COEFF  # 0 = flat earth


@dataclass(eq=False)
class ExposureSurface:
    terrain: object  # planner.terrain.Terrain
    outposts: list
    params: ExposureParams
    # float64 [rows, cols]: min over outposts of the lowest seen altitude, m AMSL
    # (inf = never seen); a proven lower bound of the exact value (the safe side),
    # tight up to ground + ceiling_agl and possibly loose above (E is capped there)
    lowest_seen: np.ndarray
    exposure: np.ndarray  # float64 [rows, cols]: E, m AMSL; NaN where not flyable
    flyable: np.ndarray  # bool [rows, cols]
    regions: np.ndarray  # int32 [rows, cols]: connected flyable regions 1..n (0: not flyable)

    @property
    def ceiling(self) -> np.ndarray:
        """Highest altitude flown (E - hide_margin), NaN where not flyable."""
        return self.exposure - self.params.hide_margin_m

    @property
    def floor(self) -> np.ndarray:
        """Lowest altitude flown (ground + clearance, on the upper ground)."""
        return self.terrain.upper + self.params.clearance_m

    @property
    def n_regions(self) -> int:
        return int(self.regions.max(initial=0))


def compute_exposure(terrain, outposts, params=ExposureParams(), progress=None) -> ExposureSurface:
    """The exposure surface of ``terrain`` under ``outposts``.

    ``progress``: optional callable(done, total) called as outposts are swept.
    """
    lowest = lowest_seen(terrain, outposts, params, progress)
    return surface_from_lowest(terrain, outposts, params, lowest)


def lowest_seen(terrain, outposts, params=ExposureParams(), progress=None) -> np.ndarray:
    """float64 [rows, cols]: the minimum over outposts of the lowest altitude
    each sees at every cell, m AMSL (+inf: never seen), as a proven lower bound
    (the safe side), tight up to ground + ceiling_agl (E is capped above)."""
    h = _heights(terrain)
    eyes = _eyes(terrain, outposts)
    if len(eyes) == 0:
        return np.full(h.shape, np.inf)
    lowest = np.empty(h.shape)  # the first outpost writes it
    threads = numba.get_num_threads()
    for n, eye in enumerate(eyes):
        k.lowest_seen_into(h, terrain.cell_size, eye, float(params.curvature_coeff),
                           float(params.ceiling_agl_m), lowest, threads, n == 0)
        if progress is not None:
            progress(n + 1, len(eyes))
    return lowest


def surface_from_lowest(terrain, outposts, params, lowest) -> ExposureSurface:
    """Cap, flyable rule and regions from the lowest seen altitude grid.

    Only solid cells are flyable (`Terrain.solid`: the surface is known all
    around them): not next to nodata, voids or the grid's edge, where a
    waypoint rounded for MAVLink could leave what is proven."""
    with np.errstate(invalid="ignore"):
        capped = np.minimum(lowest, terrain.height + params.ceiling_agl_m)
        flyable = terrain.solid & (capped - params.hide_margin_m
                                   >= terrain.upper + params.clearance_m)
    return ExposureSurface(terrain=terrain, outposts=list(outposts), params=params,
                           lowest_seen=lowest, exposure=np.where(flyable, capped, np.nan),
                           flyable=flyable, regions=_regions(flyable))


def restricted(surface, inside) -> ExposureSurface:
    """The surface with nothing flyable outside ``inside`` (bool [rows, cols]: an
    area of operations); what is hidden (``lowest_seen``) is unchanged."""
    flyable = surface.flyable & inside
    return replace(surface, exposure=np.where(flyable, surface.exposure, np.nan),
                   flyable=flyable, regions=_regions(flyable))


def _regions(flyable) -> np.ndarray:
    """int32 [rows, cols]: the connected flyable regions 1..n (8-connected), 0 elsewhere."""
    regions, _ = ndimage.label(flyable, structure=np.ones((3, 3), bool))
    return regions.astype(np.int32)


def is_hidden(surface, xyz) -> np.ndarray:
    """Exact: for each point (x, y, alt AMSL), that no outpost sees it.

    Points off the terrain grid are not proven hidden (False).
    """
    terrain = surface.terrain
    xyz = np.atleast_2d(np.asarray(xyz, float))
    row, col = terrain.rowcol(xyz[:, 0], xyz[:, 1])
    pts = np.ascontiguousarray(np.stack([col, row, xyz[:, 2]], axis=1))
    hidden = k.points_hidden(_heights(terrain), terrain.cell_size,
                             _eyes(terrain, surface.outposts), pts,
                             float(surface.params.curvature_coeff))
    return hidden & terrain.contains_xy(xyz[:, 0], xyz[:, 1]) & np.isfinite(xyz[:, 2])


def segment_hidden(surface, a_xyz, b_xyz, slack_m=0.0) -> bool:
    """Proven: every point of the straight 3-D leg a -> b (x, y, alt AMSL) is
    hidden from every outpost.

    Per outpost the leg is cut into pieces; a piece is proven by its midpoint m
    when m's exact margin below the lowest seen altitude exceeds what the
    piece can gain on it: the terrain at the horizon point of m's ray shifts by
    at most L * t* * dh for a horizontal offset dh (L: bound of the bilinear
    surface's gradient near it, t*: its fraction of the ray) and the sight line
    by t* * dz, so margin > (L + 2 k r_max / R) half_h + half_z suffices
    (details in exposure_kernels._leg_hidden_from). Pieces that fail are
    halved; a seen midpoint ends the test. Conservative: False for a leg that
    grazes a sight line within about a millimetre, leaves the grid, or crosses
    a void. With ``slack_m`` > 0 every point within that horizontal distance of
    the leg must be hidden too: the planner's legs then stay hidden when their
    ends are rounded for MAVLink.
    """
    return bool(segments_hidden(surface, [a_xyz], [b_xyz], slack_m)[0])


def segments_hidden(surface, a_xyz, b_xyz, slack_m=0.0, horizons=None) -> np.ndarray:
    """`segment_hidden` for many legs a[k] -> b[k] at once (in parallel).

    ``horizons``: optional float [n legs, n outposts], updated in place: in, the
    distance (m) from each outpost of a horizon that may prove each leg (that of
    a neighbouring leg: a few cells of terrain are tried there before the
    whole ray; NaN for none), out, the horizon found for each leg (else its
    hint). A hint saves whole-ray walks and may prove a leg that
    would not be proven without it (each proof is as strict), never the reverse."""
    terrain = surface.terrain
    a, b, inside = _legs_grid(terrain, a_xyz, b_xyz)
    if horizons is None:
        horizons = np.full((len(a), len(surface.outposts)), np.nan)
    hidden = k.legs_hidden(_heights(terrain), terrain.cell_size, _gradient_bound(surface),
                           _eyes(terrain, surface.outposts), a, b,
                           float(surface.params.curvature_coeff), float(slack_m), horizons)
    return hidden & inside


def segment_clear(surface, a_xyz, b_xyz) -> bool:
    """Exact: every point of the leg a -> b is at least clearance_m above the
    terrain (its upper surface); False over a void."""
    return bool(segments_clear(surface, [a_xyz], [b_xyz])[0])


def segments_clear(surface, a_xyz, b_xyz) -> np.ndarray:
    terrain = surface.terrain
    a, b, inside = _legs_grid(terrain, a_xyz, b_xyz)
    lowest = k.legs_height_range(np.ascontiguousarray(terrain.upper, np.float64), a, b)[:, 0]
    with np.errstate(invalid="ignore"):
        return inside & (lowest >= surface.params.clearance_m - 1e-6)


def segments_under_ceiling(surface, a_xyz, b_xyz) -> np.ndarray:
    """Exact, per leg a[k] -> b[k]: every point at most ceiling_agl_m above the
    terrain, measured from its lower surface (the highest the height above the
    real ground can be); False over a void. The ceiling is the legal limit the
    plan was made under (120 m by default), part of what every mission satisfies."""
    terrain = surface.terrain
    a, b, inside = _legs_grid(terrain, a_xyz, b_xyz)
    highest = k.legs_height_range(_heights(terrain), a, b)[:, 1]
    with np.errstate(invalid="ignore"):
        return inside & (highest <= surface.params.ceiling_agl_m + 1e-6)


# --- helpers ----------------------------------------------------------------------------------

def _heights(terrain) -> np.ndarray:
    return np.ascontiguousarray(terrain.height, dtype=np.float64)


def _eyes(terrain, outposts) -> np.ndarray:
    """float64 [n, 4]: grid (u, v), eye altitude AMSL and range of each outpost."""
    x = np.array([o.x for o in outposts], float)
    y = np.array([o.y for o in outposts], float)
    row, col = terrain.rowcol(x, y)
    # the source DEM's ground where known, else the upper surface (a higher eye sees more)
    ground = np.array([o.ground_m for o in outposts], float).reshape(-1)
    ground = np.where(np.isfinite(ground), ground, terrain.ground(x, y, upper=True))
    for o, g in zip(outposts, ground):
        if not np.isfinite(g):
            raise ValueError(f"outpost {o.name or (o.x, o.y)} is off the terrain or on a void")
    return np.stack([col, row, ground + np.array([o.height_m for o in outposts], float),
                     np.array([o.range_m for o in outposts], float)], axis=1).reshape(-1, 4)


def _legs_grid(terrain, a_xyz, b_xyz):
    """Legs as (u, v, z) rows in grid coordinates, and whether both ends are on the grid."""
    a = np.atleast_2d(np.asarray(a_xyz, float))
    b = np.atleast_2d(np.asarray(b_xyz, float))
    out = []
    for p in (a, b):
        row, col = terrain.rowcol(p[:, 0], p[:, 1])
        out.append(np.ascontiguousarray(np.stack([col, row, p[:, 2]], axis=1)))
    inside = terrain.contains_xy(a[:, 0], a[:, 1]) & terrain.contains_xy(b[:, 0], b[:, 1])
    inside &= np.isfinite(a[:, 2]) & np.isfinite(b[:, 2])
    return out[0], out[1], inside


def _gradient_bound(surface) -> np.ndarray:
    grad = surface.__dict__.get("_grad")
    if grad is None:
        terrain = surface.terrain
        grad = k.patch_gradient_bound(_heights(terrain), terrain.cell_size)
        surface.__dict__["_grad"] = grad
    return grad
