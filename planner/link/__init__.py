"""Stage 7, link: where the fleet can hear its ground station, and where it cannot.

What hides a vehicle from the outposts hides it from our own radio too: a route
behind a ridge is out of the ground station's line of sight. The ground station's
antenna and any relay sites are observers whose sight we *want*: an `Antenna`
(a mast above the ground at a point) reaches a vehicle when the vehicle is within
the radio's range and the first Fresnel zone of the ray between them is clear of
the ground to the radio's stated fraction (`kernels.ray_clear`: the same exact
bilinear terrain and Earth curvature as the exposure proofs).

`silences` samples a vehicle's planned trajectory on the fleet clock and returns
its out-of-contact windows: the monitor then knows which silences to expect
(`gcs.monitor`), and the plan says how long each vehicle will be out of contact.
"""

from dataclasses import dataclass

import numpy as np

from planner.exposure.los import DEFAULT_CURVATURE_COEFF

from . import kernels

#: m/s
LIGHT_MPS = 299_792_458.0
#: fleet seconds between two looks along a trajectory: a window's ends are this exact
STEP_S = 1.0


@dataclass(frozen=True)
class Radio:
    """The link between the ground station and each vehicle. Defaults: a 915 MHz
    telemetry radio (SiK: RFD900, Holybro), 5 km of range (stock dipoles, a few
    kilometres in the field; an RFD900 with better antennas reaches 40 km: say it
    with ``range_m``), 60 % of the first Fresnel zone clear (the usual rule for a
    link close to free space)."""

    frequency_mhz: float = 915.0
    range_m: float = 5000.0
    fresnel: float = 0.6
    # this close, the link is taken as heard whatever the ground between: a vehicle on
    # its pad beside the ground station (its ray grazes the ground), at a margin of
    # 34 dB of free-space loss over the range (20 log10(5000 / 100)), more than a
    # ray grazing an obstacle loses (6 dB) and than a deep one (about 20 dB)
    near_m: float = 100.0

    @property
    def wavelength_m(self) -> float:
        return LIGHT_MPS / (self.frequency_mhz * 1e6)


@dataclass(frozen=True)
class Antenna:
    """The ground station's antenna, or a relay's: ``mast_m`` above the ground at
    (``lat``, ``lon``)."""

    lat: float
    lon: float
    mast_m: float = 2.0


def antenna_eyes(terrain, antennas) -> np.ndarray:
    """float64 [n, 3]: grid (u, v) and altitude AMSL of each antenna's top; ValueError
    for one off the terrain or on a void."""
    out = []
    for a in antennas:
        x, y = terrain.from_lonlat(a.lon, a.lat)
        ground = float(terrain.ground(x, y, upper=True)[0])
        if not np.isfinite(ground):
            raise ValueError(f"antenna at {a.lat:.6f},{a.lon:.6f} is off the terrain or on "
                             "a void")
        row, col = terrain.rowcol(x, y)
        out.append((float(col), float(row), ground + a.mast_m))
    return np.array(out, float).reshape(-1, 3)


def in_contact(terrain, antennas, radio: Radio, xyz, curvature_coeff=DEFAULT_CURVATURE_COEFF
               ) -> np.ndarray:
    """bool [n]: whether some antenna reaches each point (x, y, alt AMSL)."""
    xyz = np.atleast_2d(np.asarray(xyz, float))
    if not len(xyz) or not antennas:
        return np.zeros(len(xyz), bool)
    row, col = terrain.rowcol(xyz[:, 0], xyz[:, 1])
    points = np.ascontiguousarray(np.stack([col, row, xyz[:, 2]], axis=1))
    return kernels.in_contact(np.ascontiguousarray(terrain.height, np.float64),
                              terrain.cell_size, antenna_eyes(terrain, antennas), points,
                              radio.wavelength_m, radio.fresnel, radio.range_m, radio.near_m,
                              float(curvature_coeff))


def contact_at(terrain, antennas, radio: Radio, curvature_coeff=DEFAULT_CURVATURE_COEFF):
    """``heard(lat, lon, alt AMSL) -> bool``: whether some antenna reaches a vehicle
    there (the simulator's radio, `gcs.sim`). False off the terrain: nothing is
    known to reach it."""
    eyes = antenna_eyes(terrain, antennas)
    height = np.ascontiguousarray(terrain.height, np.float64)

    def heard(lat: float, lon: float, alt: float) -> bool:
        x, y = terrain.from_lonlat(lon, lat)
        if not terrain.contains_xy(np.atleast_1d(x), np.atleast_1d(y)).all():
            return False
        row, col = terrain.rowcol(x, y)
        # one point, serially: a parallel kernel's start costs a thousand times more
        return bool(kernels.reaches(height, terrain.cell_size, eyes, float(col), float(row),
                                    float(alt), radio.wavelength_m, radio.fresnel,
                                    radio.range_m, radio.near_m, float(curvature_coeff)))
    return heard


@dataclass
class Silences:
    """A vehicle's predicted radio silences on the fleet clock."""

    windows: list          # [(first s out of contact, last s out of contact)]
    airborne_s: float      # in the air, in all
    silent_s: float        # of it, out of contact

    @property
    def longest_s(self) -> float:
        return max((b - a for a, b in self.windows), default=0.0)

    @property
    def share(self) -> float:
        return self.silent_s / self.airborne_s if self.airborne_s > 0 else 0.0


def silences(terrain, antennas, radio: Radio, trajectory, flights, step_s=STEP_S,
             curvature_coeff=DEFAULT_CURVATURE_COEFF) -> Silences:
    """The windows in which a vehicle is out of contact: ``trajectory`` rows (t, x, y,
    alt AMSL) on the fleet clock, linear between them, sampled every ``step_s``
    within its ``flights`` ((takeoff s, landing s) of each sortie)."""
    rows = np.asarray(trajectory, float)
    times = np.concatenate([np.arange(a, b, step_s) for a, b in flights] or [np.zeros(0)])
    if not len(times):
        return Silences([], 0.0, 0.0)
    xyz = np.stack([np.interp(times, rows[:, 0], rows[:, k]) for k in (1, 2, 3)], axis=1)
    heard = in_contact(terrain, antennas, radio, xyz, curvature_coeff)
    windows = []
    for a, b in flights:
        inside = (times >= a) & (times < b)
        t, silent = times[inside], ~heard[inside]
        edges = np.flatnonzero(np.diff(np.r_[0, silent.astype(np.int8), 0]))
        windows += [(float(t[i]), float(t[j - 1])) for i, j in zip(edges[::2], edges[1::2])]
    airborne = float(sum(b - a for a, b in flights))
    return Silences(windows, airborne, float(step_s * np.count_nonzero(~heard)))


def fleet_silences(terrain, antennas, radio: Radio, fleet, r) -> Silences:
    """UAV r's silences on the fleet clock of a `planner.fleet.clock.Fleet`: its
    trajectory while it is in the air."""
    return silences(terrain, antennas, radio, fleet.track(r),
                    [fleet.airborne(i) for i in fleet.of(r)])


__all__ = ["Antenna", "Radio", "Silences", "antenna_eyes", "contact_at", "fleet_silences",
           "in_contact", "silences"]
