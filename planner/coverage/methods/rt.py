"""RT, the paper's reduced-time method: PTV allocation with threshold adaptation
(`search.greedy`)."""

from dataclasses import dataclass
from typing import Optional

from .registry import register


@dataclass
class GreedyParams:
    """The settings of the greedy engine RT and RD run on (`search.greedy`).

    ``alpha``, ``beta``: the exponents of M_PTV and of the spread-out phase.
    ``step_time_cap`` is th_ra in seconds; None picks ``step_cap_factor`` times
    the median nearest-neighbour travel time between viewpoints (chosen by
    benchmarks/bench_coverage.py), ``math.inf`` disables the cap."""

    alpha: float = 0.55
    beta: float = 0.3
    step_time_cap: Optional[float] = None
    step_cap_factor: float = 4.0


@dataclass
class RtParams(GreedyParams):
    """RT's settings: the greedy engine's, and whether phase 3 (threshold
    adaptation) runs."""

    threshold_adaptation: bool = True


@register("rt", "the paper's reduced-time method (PTV allocation, threshold adaptation)",
          "the paper's", RtParams, order=1)
def run(prep, params, progress):
    from ..search.greedy import allocate  # when it runs: this package stays light

    return allocate(prep, params, "ptv", progress=progress)
