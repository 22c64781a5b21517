"""RT+LS: RT, then our local search (`search.local_search`), from a few th_ra."""

from dataclasses import dataclass, replace

from .registry import register
from .rt import RtParams


@dataclass
class RtLsParams(RtParams):
    """RT+LS's settings: RT's, and ``ls_starts`` RT starts (th_ra factor x1, x0.5,
    x2), each followed by ``ls_rounds`` rounds of local search."""

    ls_rounds: int = 20
    ls_starts: int = 3


@register("rt+ls", "RT, then our local search (drop, relocate, swap, replace, re-route)",
          "rt + our local search", RtLsParams, order=2)
def run(prep, params, progress):
    """RT, then local search; restarted with th_ra halved and doubled, best kept.

    The first start is plain RT with ``params``, so the result is never worse
    than RT.  Restarts only apply when th_ra comes from the factor.
    """
    # when it runs: this package stays light
    from ..model.evaluation import evaluate
    from ..search.greedy import allocate
    from ..search.local_search import local_search

    factors = [params.step_cap_factor]
    if params.step_time_cap is None:
        factors += [params.step_cap_factor * f for f in (0.5, 2.0)][:max(params.ls_starts - 1, 0)]
    best = first = None
    for i, factor in enumerate(factors):
        p = replace(params, step_cap_factor=factor)
        routes, steps = allocate(prep, p, "ptv", progress=progress if i == 0 else None)
        first = first or (routes, steps)
        for r in (routes, local_search(prep, routes, params.ls_rounds)):
            a = evaluate(prep, r, "rt+ls")
            if a.covered and (best is None or a.coverage_time < best[0] - 1e-9):
                best = (a.coverage_time, r, steps)
    # none covering: RT's, left short by the one-UAV-a-viewpoint rule (`search.share`)
    return (best[1], best[2]) if best is not None else first
