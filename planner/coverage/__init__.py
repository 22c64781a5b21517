"""Coverage allocation: which UAV photographs from which viewpoint, in what order.

Pure combinatorics over a :class:`CoverageProblem` (visibility sets, hidden
travel times, optional launch points), in four parts:

- ``model``: the problem, each UAV's battery, route times, the sightings rule
  and the evaluation of a plan;
- ``methods``: the coverage methods, one module each, registered with their
  own settings: ``rt`` (the paper's reduced-time method), ``rt+ls`` (RT
  followed by our local search), ``alns`` (our adaptive large-neighbourhood
  search, the default), ``rd`` (per-distance baseline), ``b`` (dominating set,
  then routing), ``c`` (time clustering, then dominating set and tour per
  cluster);
- ``search``: the code the methods are made of (greedy phases, local search,
  ALNS, set cover, routing);
- ``bounds``: lower bounds on coverage time, and the proven optimum of small
  problems (the tests' oracle).

`solve` (``solver``) runs a method. The names below are imported when first
used, not with this package: `methods` is read by the command line, which must
not load numba for it.
"""

from importlib import import_module

#: the public names, each with the module it comes from
_FROM = {
    "Allocation": ".model", "CoverageProblem": ".model", "coverage_counts": ".model",
    "prepare": ".model", "required_uavs": ".model", "sighting_counts": ".model",
    "lower_bound": ".bounds", "lower_bounds": ".bounds",
    "METHODS": ".methods", "solve": ".solver",
}
__all__ = ["METHODS", "Allocation", "CoverageProblem", "coverage_counts", "lower_bound",
           "lower_bounds", "prepare", "required_uavs", "sighting_counts", "solve"]


def __getattr__(name):
    if name not in _FROM:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(import_module(_FROM[name], __name__), name)
    globals()[name] = value
    return value
