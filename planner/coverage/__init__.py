"""Coverage allocation: which UAV photographs from which viewpoint, in what order.

Pure combinatorics over a :class:`CoverageProblem` (visibility sets, hidden
travel times, optional launch points).  Methods: ``rt`` (the paper's
reduced-time method), ``rt+ls`` (RT followed by our local search), ``alns``
(our adaptive large-neighbourhood search, the default), ``rd``
(per-distance baseline), ``b`` (dominating set, then routing), ``c`` (time
clustering, then dominating set and tour per cluster).

Modules, one piece each: problem (data model), gains (fault-tolerant V),
objectives (So, M_PTV, M_PTV2, per-distance), insertion (edge-breaking rule,
route times), greedy (RT/RD phases), setcover, routing (OR-Tools), baselines
(B, C), local_search (RT+LS), alns and alns_kernels (ALNS), metrics
(evaluation, reach and packing bounds), bounds (the flow LP bound and the best
of all), exact (the proven optimum of small problems: the tests' oracle), solve.
"""

from .bounds import bounds, lower_bound
from .metrics import coverage_counts
from .problem import Allocation, CoverageParams, CoverageProblem, prepare, required_uavs
from .solve import METHODS, solve

__all__ = ["Allocation", "CoverageParams", "CoverageProblem", "METHODS", "bounds",
           "coverage_counts", "lower_bound", "prepare", "required_uavs", "solve"]
