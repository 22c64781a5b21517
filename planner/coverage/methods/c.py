"""C, the paper's baseline: time clustering, then a dominating set and a tour per
cluster (`search.baselines`)."""

from .b import BaselineParams
from .registry import register


@register("c", "baseline C: time clustering, then a dominating set and a tour per cluster",
          "baseline", BaselineParams, order=6)
def run(prep, params, progress):
    from ..search.baselines import solve_c  # when it runs: this package stays light

    return solve_c(prep, params), []
