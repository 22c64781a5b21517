"""One local metric frame for everything that turns latitude and longitude into
metres over a few kilometres: the ground station's guard, monitor and corridor,
the mission files' geometry, and the simulator.

`LocalFrame` is the azimuthal equidistant projection of the WGS 84 ellipsoid
around an origin (PROJ's ``aeqd``, through pyproj): within 10 km of the origin its
distances are the geodesic ones to better than a millimetre, and it inverts to
1e-9 degree (a waypoint survives the round trip). The simpler frames it replaces
scaled degrees by one Earth radius at the origin's latitude: the mean radius
(6,371.0 km) the ground station used is 0.2 % off the ellipsoid's north-south
and east-west radii at 36.5 degrees, the equatorial one (6,378.1 km) the
simulator used differs from it by 0.1 %, and at a fixed latitude's scale the
meridians' convergence alone puts a point 5 km north-east of the origin 2 m off
at 36.5 degrees, 7 m at 60: more than a track tolerance can spare.
"""

import numpy as np
from pyproj import Geod, Transformer

_GEOD = Geod(ellps="WGS84")


class LocalFrame:
    """Metres east (x) and north (y) of (``lat0``, ``lon0``); altitudes pass through."""

    def __init__(self, lat0: float, lon0: float):
        self.lat0, self.lon0 = float(lat0), float(lon0)
        self._to_local = Transformer.from_pipeline(
            f"+proj=aeqd +lat_0={self.lat0!r} +lon_0={self.lon0!r} +ellps=WGS84 +units=m")

    def __repr__(self) -> str:
        return f"LocalFrame({self.lat0!r}, {self.lon0!r})"

    def to_local(self, lat, lon) -> tuple:
        """(x, y) metres of ``lat``, ``lon`` (floats, or arrays of them)."""
        return self._to_local.transform(lon, lat)

    def to_geo(self, x, y) -> tuple:
        """(lat, lon) of ``x``, ``y`` metres."""
        lon, lat = self._to_local.transform(x, y, direction="INVERSE")
        return lat, lon

    def project(self, points) -> np.ndarray:
        """[n, 3] metres east, north and altitude of ``points`` [(lon, lat, alt), ...]."""
        if len(points) == 0:
            return np.zeros((0, 3))
        a = np.asarray(points, float).reshape(-1, 3)
        x, y = self._to_local.transform(a[:, 0], a[:, 1])
        return np.column_stack([x, y, a[:, 2]])


def distance_m(lat1, lon1, lat2, lon2) -> float:
    """Horizontal (geodesic) distance in metres between two points."""
    return float(_GEOD.inv(lon1, lat1, lon2, lat2)[2])


__all__ = ["LocalFrame", "distance_m"]
