"""Stage 4, travel: hidden travel times and paths between viewpoints.

Modules: params (`TravelParams` and the time of legs, takeoffs and landings),
graph (the hidden travel graph: its proven legs, attaching points to it, times,
paths and their string pulling), overlay (the sparse overlay of a set of
points: their times on a large area), kernels (numba).
"""

from .graph import CLEARANCE_MARGIN_M, TravelGraph, build_travel_graph, raised_terrain
from .overlay import overlay_rows
from .params import (
    ROUNDING_SLACK_M,
    TravelParams,
    landing_time,
    leg_time,
    polyline_time,
    takeoff_time,
)

__all__ = ["CLEARANCE_MARGIN_M", "ROUNDING_SLACK_M", "TravelGraph", "TravelParams",
           "build_travel_graph", "landing_time", "leg_time", "overlay_rows", "polyline_time",
           "raised_terrain", "takeoff_time"]
