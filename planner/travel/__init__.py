"""Stage 4, travel: hidden travel times and paths between viewpoints.

Modules: graph (the hidden travel graph, leg checks, shortest paths, string
pulling), kernels (numba).
"""

from .graph import (
                    CLEARANCE_MARGIN_M,
                    ROUNDING_SLACK_M,
                    TravelGraph,
                    TravelParams,
                    build_travel_graph,
                    landing_time,
                    leg_time,
                    overlay_rows,
                    polyline_time,
                    raised_terrain,
                    takeoff_time,
)

__all__ = ["CLEARANCE_MARGIN_M", "ROUNDING_SLACK_M", "TravelGraph", "TravelParams", "build_travel_graph",
           "landing_time", "leg_time", "overlay_rows", "polyline_time", "raised_terrain", "takeoff_time"]
