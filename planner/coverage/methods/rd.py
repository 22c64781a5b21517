"""RD, the paper's per-distance baseline: RT's starts, no threshold adaptation
(`search.greedy`)."""

from dataclasses import dataclass

from .registry import register
from .rt import GreedyParams


@dataclass
class RdParams(GreedyParams):
    """RD's settings: the greedy engine's (it has no threshold adaptation)."""


@register("rd", "the per-distance baseline (same starts, no threshold adaptation)",
          "baseline", RdParams, order=4)
def run(prep, params, progress):
    from ..search.greedy import allocate  # when it runs: this package stays light

    return allocate(prep, params, "per_distance", progress=progress)
