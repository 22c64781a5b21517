"""ALNS, ours: an adaptive large-neighbourhood search from RT (and RT+LS), within a
work budget (`search.alns`)."""

from dataclasses import dataclass
from typing import Optional

from .registry import method, register
from .rt_ls import RtLsParams


@dataclass
class AlnsParams(RtLsParams):
    """ALNS's settings: those of its starts (RT, RT+LS), the ``seed`` of its
    random draws, ``time_budget_s`` (None: scaled to the problem,
    `search.alns.default_budget_s`), and ``budget_fraction``, which caps the
    budget at that fraction of the start plan's coverage time (re-planning in
    flight)."""

    seed: int = 0
    time_budget_s: Optional[float] = None
    budget_fraction: Optional[float] = None


@register("alns", "ours: adaptive large-neighbourhood search from RT (and RT+LS), "
                  "within --time-budget", "ours: large-neighbourhood search, the best",
          AlnsParams, order=3)
def run(prep, params, progress):
    """RT, polished; RT+LS too where it is affordable (so never worse than it
    there); then the search from the better one."""
    from ..search.alns import LS_START_SIZE, search  # when it runs: this package stays light

    rt_progress = (lambda f: progress(0.2 * f)) if progress is not None else None
    routes, _ = method("rt").run(prep, params, rt_progress)
    starts = [routes]
    if prep.problem.n_viewpoints * prep.problem.n_uavs <= LS_START_SIZE:
        starts.append(method("rt+ls").run(prep, params, None)[0])
    result = search(prep, starts, params, progress=(lambda f: progress(0.2 + 0.8 * f))
                    if progress is not None else None)
    return result.routes, []
