"""Stage 2, exposure: where a UAV is hidden from the outposts.

Modules: outposts (the `Outpost` model and its GeoJSON reader), los (exact line
of sight over the bilinear terrain), kernels (the ring sweep and the leg
proofs, numba), surface (the exposure surface E, its flyable regions and the
hidden / clear tests every leg passes).
"""

from .outposts import Outpost, load_outposts, outposts_to_geojson, sample_outposts
from .surface import (
                      ExposureParams,
                      ExposureSurface,
                      compute_exposure,
                      is_hidden,
                      lowest_seen,
                      restricted,
                      segment_clear,
                      segment_hidden,
                      segments_clear,
                      segments_hidden,
                      segments_under_ceiling,
                      surface_from_lowest,
)

__all__ = ["ExposureParams", "ExposureSurface", "Outpost", "compute_exposure", "is_hidden",
           "load_outposts", "lowest_seen", "outposts_to_geojson", "restricted", "sample_outposts",
           "segment_clear", "segment_hidden", "segments_clear", "segments_hidden",
           "segments_under_ceiling", "surface_from_lowest"]
