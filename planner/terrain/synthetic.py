"""Seeded synthetic terrains for tests and benchmarks, on a real UTM grid.

Families:
- ``hills``: smooth rolling hills (isotropic FFT-filtered noise, ~1.5 km features);
- ``ridges``: long parallel ridges and valleys (noise stretched along one strike);
- ``peaks``: isolated gaussian peaks on gently undulating ground;
- ``mixed``: a blend of the three.
Relief is a few hundred metres; the steepest slope is capped (`MAX_SLOPE_DEG`)
by scaling the relief down, so the terrain stays plausible at any cell size.
"""

import numpy as np
from affine import Affine
from pyproj import Transformer

from .dem import utm_crs
from .grid import Terrain

FAMILIES = ("hills", "ridges", "peaks", "mixed")
BASE_M = 300.0  # height of the lowest ground, metres AMSL
RELIEF_M = 400.0  # target range of heights before the slope cap
MAX_SLOPE_DEG = 35.0


def synthetic_terrain(n_rows=256, n_cols=256, cell=30.0, seed=0, family="hills",
                      lat=36.6, lon=-84.2) -> Terrain:
    """A ``n_rows`` x ``n_cols`` terrain of ``cell`` metres centred on (lat, lon)."""
    if family not in FAMILIES:
        raise ValueError(f"family must be one of {', '.join(FAMILIES)}, got {family!r}")
    rng = np.random.default_rng(seed)
    shape = (int(n_rows), int(n_cols))
    if family == "mixed":
        parts = [_normalised(_FAMILY[f](shape, cell, rng)) for f in ("hills", "ridges", "peaks")]
        surface = 0.35 * parts[0] + 0.35 * parts[1] + 0.5 * parts[2]
    else:
        surface = _FAMILY[family](shape, cell, rng)
    height = BASE_M + RELIEF_M * _normalised(surface)
    height = _cap_slope(height, cell)
    crs = utm_crs(lon, lat)
    x0, y0 = Transformer.from_crs("EPSG:4326", crs, always_xy=True).transform(lon, lat)
    left = np.round(x0 / cell) * cell - shape[1] * cell / 2
    top = np.round(y0 / cell) * cell + shape[0] * cell / 2
    transform = Affine(cell, 0.0, left, 0.0, -cell, top)
    return Terrain(height, transform, crs, source=f"synthetic {family} seed={seed}",
                   meta={"family": family, "seed": seed})


def _filtered_noise(shape, cell, rng, length_m, strike_deg=None, stretch=1.0):
    """White noise low-passed with a gaussian of ``length_m`` (stretched ``stretch``
    times along ``strike_deg``, azimuth from north), via FFT."""
    noise = rng.standard_normal(shape)
    ky = np.fft.fftfreq(shape[0], d=cell)[:, None]
    kx = np.fft.rfftfreq(shape[1], d=cell)[None, :]
    if strike_deg is not None:
        a = np.radians(strike_deg)
        along = kx * np.sin(a) + ky * np.cos(a)
        across = kx * np.cos(a) - ky * np.sin(a)
        k2 = (along * stretch) ** 2 + across**2
    else:
        k2 = kx**2 + ky**2
    spectrum = np.fft.rfft2(noise) * np.exp(-2 * (np.pi * length_m) ** 2 * k2)
    return np.fft.irfft2(spectrum, s=shape)


def _hills(shape, cell, rng):
    broad = _normalised(_filtered_noise(shape, cell, rng, 600.0))
    return broad + 0.15 * _normalised(_filtered_noise(shape, cell, rng, 200.0))


def _ridges(shape, cell, rng):
    strike = rng.uniform(0, 180)
    n = _filtered_noise(shape, cell, rng, 450.0, strike_deg=strike, stretch=6.0)
    n = n / (np.abs(n).max() + 1e-12)
    ridged = 1.0 - np.sqrt(n**2 + 0.1**2)  # crests where the noise crosses zero, rounded
    return ridged**2 + 0.2 * _normalised(_filtered_noise(shape, cell, rng, 800.0))


def _peaks(shape, cell, rng):
    n_rows, n_cols = shape
    ground = 0.15 * _normalised(_filtered_noise(shape, cell, rng, 800.0))
    n_peaks = max(3, int(n_rows * n_cols * cell**2 / 4e6))  # about one per 4 km^2
    cx = rng.uniform(0, n_cols * cell, n_peaks)
    cy = rng.uniform(0, n_rows * cell, n_peaks)
    sigma = rng.uniform(250.0, 700.0, n_peaks)
    amp = rng.uniform(0.4, 1.0, n_peaks)
    bumps = np.zeros(shape)
    for i in range(n_peaks):  # one vectorised gaussian per peak, within 4 sigma of it
        r = 4 * sigma[i] / cell
        rows = np.arange(max(int(cy[i] / cell - r), 0), min(int(cy[i] / cell + r) + 1, n_rows))
        cols = np.arange(max(int(cx[i] / cell - r), 0), min(int(cx[i] / cell + r) + 1, n_cols))
        d2 = ((cols[None, :] + 0.5) * cell - cx[i]) ** 2 + ((rows[:, None] + 0.5) * cell
                                                            - cy[i]) ** 2
        bumps[np.ix_(rows, cols)] += amp[i] * np.exp(-d2 / (2 * sigma[i] ** 2))
    return ground + bumps


_FAMILY = {"hills": _hills, "ridges": _ridges, "peaks": _peaks}


def _normalised(a):
    span = a.max() - a.min()
    return (a - a.min()) / span if span > 0 else np.zeros_like(a)


def _cap_slope(height, cell):
    gy, gx = np.gradient(height, cell)
    steepest = np.degrees(np.arctan(np.hypot(gx, gy).max()))
    if steepest <= MAX_SLOPE_DEG:
        return height
    scale = np.tan(np.radians(MAX_SLOPE_DEG)) / np.tan(np.radians(steepest))
    return BASE_M + (height - BASE_M) * scale
