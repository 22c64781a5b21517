"""B, the paper's baseline: a greedy dominating set, then OR-Tools makespan routing
(`search.baselines`)."""

from dataclasses import dataclass
from typing import Optional

from .registry import register
from .rt import RtParams


@dataclass
class BaselineParams(RtParams):
    """The settings of B and C: RT's (the repair of a target left short), the
    ``seed`` of the time clustering, ``routing_solutions`` per OR-Tools search
    (deterministic) and ``routing_time_s``, a safety-net time limit (None: scaled
    to the size), and ``ls_rounds`` of the routing local search that ends them."""

    seed: int = 0
    routing_time_s: Optional[float] = None
    routing_solutions: int = 20
    ls_rounds: int = 20


@register("b", "baseline B: greedy dominating set, then OR-Tools makespan routing",
          "baseline", BaselineParams, order=5)
def run(prep, params, progress):
    from ..search.baselines import solve_b  # when it runs: this package stays light

    return solve_b(prep, params), []
