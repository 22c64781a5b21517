"""The one local metric frame (`common.geo`) against pyproj's geodesic on the WGS 84
ellipsoid, an independent reference, over areas of a few kilometres anywhere:
southern, western, high latitudes."""

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pyproj import Geod

from common.geo import LocalFrame, distance_m

GEOD = Geod(ellps="WGS84")


@settings(max_examples=200, deadline=None)
@given(lat=st.floats(-70.0, 70.0), lon=st.floats(-179.0, 179.0),
       azimuth=st.floats(-180.0, 180.0), far=st.floats(1.0, 5000.0))
def test_distances_over_a_few_km_are_the_geodesic_ones(lat, lon, azimuth, far):
    lon2, lat2, _ = GEOD.fwd(lon, lat, azimuth, far)
    true = GEOD.inv(lon, lat, lon2, lat2)[2]
    assert distance_m(lat, lon, lat2, lon2) == pytest.approx(true, rel=1e-9, abs=1e-6)
    frame = LocalFrame(lat, lon)
    x, y = frame.to_local(lat2, lon2)
    assert math.hypot(x, y) == pytest.approx(true, rel=1e-9, abs=1e-6)
    back = frame.to_geo(x, y)                   # invertible: waypoints survive (1e-7 deg)
    assert back == pytest.approx((lat2, lon2), abs=1e-9)
    # two points 5 km on either side of the origin: a millimetre at most
    lon3, lat3, _ = GEOD.fwd(lon, lat, azimuth + 90.0, 5000.0)
    x3, y3 = frame.to_local(lat3, lon3)
    assert math.hypot(x - x3, y - y3) == pytest.approx(GEOD.inv(lon2, lat2, lon3, lat3)[2],
                                                       abs=1e-3)
