"""The scattered route bound (`bounds.scatter`): never above an optimum proven by
something else (exhaustive enumeration of tiny problems, the exact solver's cached
optima)."""

import json
from pathlib import Path

import numpy as np
from exhaustive import exhaustive_optimum, tiny
from hypothesis import given, settings
from hypothesis import strategies as st

from planner.coverage.bounds.radius import radius_bound
from planner.coverage.bounds.scatter import scatter_bound, scattered_places
from planner.coverage.model import prepare, target_classes
from planner.coverage.model.instances import optimality_case, random_problem

ROOT = Path(__file__).resolve().parents[1]
OPTIMA = (ROOT / "benchmarks" / "coverage_optimal.json",
          ROOT / "benchmarks" / "coverage_optimal_mid.json")


def _scatter(problem, sizes, time_limit=2.0):
    """The bound forced onto a small problem, from its radius bound (0 if none)."""
    prep = target_classes(prepare(problem))[0]
    lower = radius_bound(prep)
    return scatter_bound(prep, lower, time_limit, sizes=sizes, min_useful=0) if lower > 0 \
        else 0.0


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 10_000), st.integers(3, 5), st.integers(2, 3), st.integers(0, 2),
       st.booleans(), st.sampled_from([450.0, 700.0]))
def test_never_above_the_exhaustive_optimum(seed, n_vp, n_uavs, k, launch, sensor):
    """On every subset size (the whole set included), whatever the fleet, k and launch
    (5 viewpoints with 2 UAVs, 4 with 3: the enumeration's plans grow as 326^UAVs)."""
    k = min(k, n_uavs - 1)
    n_vp = min(n_vp, 4) if n_uavs == 3 else n_vp
    problem = tiny(seed, n_vp, n_uavs, k, launch, sensor_m=sensor)
    opt = exhaustive_optimum(problem)
    for sizes in ((2,), (3,), (2, 3, 5)):
        value = _scatter(problem, sizes)
        assert value <= opt * (1 + 1e-9) + 1e-9, (sizes, value, opt)


def test_never_above_the_cached_proven_optima():
    """Every proven optimum of `bench_coverage --optimal` and `--optimal-mid` (8-30
    viewpoints), on subsets of 6 and of 12 viewpoints (the whole problem is what
    `routes.route_bound` prices; a subset is what a large problem gets). It is
    above the radius bound it starts from on a quarter of them at least."""
    checked, above_radius = 0, 0
    for path in OPTIMA:
        cases = json.loads(path.read_text())["cases"]
        for record in cases.values():
            if not record["proven"]:
                continue
            lo, hi = (17, 30) if "mid" in path.name else (8, 16)
            _, problem = optimality_case(record["seed"], lo, hi)
            prep = target_classes(prepare(problem))[0]
            lower = radius_bound(prep)
            value = scatter_bound(prep, lower, 0.5, sizes=(6, 12), min_useful=0)
            assert value <= record["value"] * (1 + 1e-9), (record, value)
            checked += 1
            above_radius += value > lower
    assert checked >= 240 and above_radius >= checked // 4, (checked, above_radius)


def test_the_places_are_the_viewers_of_anchors_farthest_first():
    """Every place taken is a viewer of a target with at most one viewer beyond its
    need, and the first is on the target farthest from the bases."""
    problem = random_problem(120, 2400, 4, k=1, seed=3, launch=True)
    prep = prepare(problem)
    places = scattered_places(prep, 12)
    assert 2 <= len(places) <= 12 and np.all(np.diff(places) > 0)
    need = prep.required
    anchors = [t for t in range(problem.n_targets)
               if need[t] > 0 and prep.tgt_indptr[t + 1] - prep.tgt_indptr[t] <= need[t] + 1]
    viewers = {int(v) for t in anchors
               for v in prep.tgt_indices[prep.tgt_indptr[t]:prep.tgt_indptr[t + 1]]}
    assert set(places.tolist()) <= viewers
    reach = prep.launch_out.min(axis=0)
    farthest = max(min(reach[prep.tgt_indices[prep.tgt_indptr[t]:prep.tgt_indptr[t + 1]]])
                   for t in anchors)
    assert max(reach[places]) >= farthest - 1e-9
