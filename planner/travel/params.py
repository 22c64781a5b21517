"""The time model of a flight: straight legs, takeoffs and landings.

A leg's time is the slower of its horizontal motion at ``speed_mps`` and its
vertical motion at ``climb_mps`` up or ``descent_mps`` down, so times are
directed; a takeoff and a landing fly their lowest metres at the firmware's
slower rates (`TravelParams`'s bands).
"""

from dataclasses import dataclass
from typing import Optional

import numpy as np

from common.errors import InputError

#: MISSION_ITEM_INT carries lat/lon in 1e-7 degree (<= 1.1 cm): every planned leg is
#: proven hidden and clear with this much room around it on top of the track
#: tolerance, so the rounded leg is too
ROUNDING_SLACK_M = 0.05


@dataclass(frozen=True)
class TravelParams:
    speed_mps: float = 12.0
    climb_mps: float = 3.0
    descent_mps: float = 2.0
    #: how far (horizontally) a vehicle may stray from a planned leg and stay hidden and
    #: clear: cross-track error and corner overshoot (the simulator's copter: up to 4 m)
    track_tolerance_m: float = 5.0
    #: the slower rates of the lowest metres of a takeoff and of a landing (a
    #: firmware's `autopilots.Rates`); None: the climb or descent rate throughout
    takeoff_mps: Optional[float] = None
    takeoff_band_m: float = 0.0
    land_mps: Optional[float] = None
    land_band_m: float = 0.0

    def __post_init__(self):
        for name in ("speed_mps", "climb_mps", "descent_mps", "takeoff_mps", "land_mps"):
            value = getattr(self, name)
            if value is not None and not value > 0:
                raise InputError(name, f"must be positive, got {value}")
        if not self.track_tolerance_m >= 0:
            raise InputError("track_tolerance_m", f"must not be negative, got "
                                                  f"{self.track_tolerance_m}")

    @property
    def slack_m(self) -> float:
        """Room around every leg that must be hidden too (segments_hidden's slack_m)."""
        return self.track_tolerance_m + ROUNDING_SLACK_M


def leg_time(horizontal_m, dz_m, params=TravelParams()):
    """Time of straight legs: the slower of horizontal and vertical motion."""
    horizontal_m = np.asarray(horizontal_m, float)
    dz_m = np.asarray(dz_m, float)
    vertical = np.where(dz_m > 0, dz_m / params.climb_mps, -dz_m / params.descent_mps)
    return np.maximum(horizontal_m / params.speed_mps, vertical)


def takeoff_time(height_m, params=TravelParams()) -> float:
    """Time of a takeoff ``height_m`` straight up: its lowest ``takeoff_band_m`` at
    ``takeoff_mps``, the rest at the climb rate."""
    return _vertical_time(height_m, params.takeoff_band_m, params.takeoff_mps, params.climb_mps)


def landing_time(height_m, params=TravelParams()) -> float:
    """Time of a landing ``height_m`` straight down: its lowest ``land_band_m`` at
    ``land_mps``, the rest at the descent rate."""
    return _vertical_time(height_m, params.land_band_m, params.land_mps, params.descent_mps)


def _vertical_time(height_m, band_m, slow_mps, rate_mps):
    h = np.maximum(np.asarray(height_m, float), 0.0)
    low = np.minimum(h, band_m if slow_mps else 0.0)
    out = low / (slow_mps or rate_mps) + (h - low) / rate_mps
    return float(out) if out.ndim == 0 else out


def polyline_time(poly, params=TravelParams()) -> float:
    """Flight time along a 3-D polyline (n, 3) under the leg time model."""
    poly = np.asarray(poly, float)
    if len(poly) < 2:
        return 0.0
    d = np.diff(poly, axis=0)
    return float(leg_time(np.hypot(d[:, 0], d[:, 1]), d[:, 2], params).sum())
