"""Stage 3, visibility: candidate viewpoints and what each one sees.

Modules: viewpoints (the lattice of candidates over the fleet's region), sets
(the sensor model and the sparse visibility sets), kernels (numba).
"""

from .sets import SensorParams, VisibilityMatrix, compute_visibility
from .viewpoints import (
                         Viewpoints,
                         candidate_viewpoints,
                         default_spacing,
                         fleet_region,
                         launch_cells,
                         viewpoints_at,
)

__all__ = ["SensorParams", "Viewpoints", "VisibilityMatrix", "candidate_viewpoints",
           "compute_visibility", "default_spacing", "fleet_region", "launch_cells",
           "viewpoints_at"]
