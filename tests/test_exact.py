"""The exact solver, judged by exhaustive enumeration of every plan, and the
methods judged by it: no plan beats the optimum, none is further above it than
the worst ratio measured for it (benchmarks/bench_coverage.py --optimal)."""

import itertools

import numpy as np
import places_reference as ref
import pytest
from exhaustive import CASES, exhaustive_optimum, tiny

from planner.coverage import METHODS, lower_bound, solve
from planner.coverage.bounds.exact import optimum
from planner.coverage.model import evaluate, prepare
from planner.coverage.model.instances import optimality_case, random_problem


@pytest.mark.parametrize("case,sensor", list(itertools.product(CASES, (450.0, 700.0))))
def test_the_optimum_is_the_exhaustive_one(case, sensor):
    problem = tiny(*case, sensor_m=sensor)
    best = exhaustive_optimum(problem)
    found = optimum(problem, time_limit_s=60)
    assert found.proven
    assert found.value == pytest.approx(best, rel=1e-9, abs=1e-6)
    # its plan is a plan: covered by the brute-force rule, timed by `evaluate`
    assert ref.shortfall(problem, found.routes) == 0
    assert evaluate(prepare(problem), found.routes, "x").coverage_time == found.value


def test_a_hint_only_starts_the_search():
    problem = tiny(3, 5, 2, 1, False, sensor_m=700.0)
    plan = solve(problem, "rd")
    found = optimum(problem, hint=plan.routes)
    assert found.proven and found.value == pytest.approx(exhaustive_optimum(problem))
    assert found.value <= plan.coverage_time


#: the worst coverage time / optimum each method reaches on `SMALL` (measured
#: 2026-11-27: ALNS 1.000, optimal on all 12 since it may share a viewpoint
#: between two UAVs (1.152 before); RT+LS 1.152, B 1.459, C 1.430, RT 1.524,
#: RD 2.240; the methods are deterministic, so a little above that is a
#: regression, not noise); benchmarks/bench_coverage.py --optimal gives the
#: larger set's figures
WORST = {"alns": 1.01, "rt+ls": 1.16, "b": 1.47, "c": 1.44, "rt": 1.53, "rd": 2.25}
SMALL = [optimality_case(seed, 8, 12) for seed in range(12)]


@pytest.mark.slow
def test_every_method_against_the_optimum():
    ratios = {m: [] for m in METHODS}
    for name, problem in SMALL:
        best = optimum(problem, time_limit_s=120)
        assert best.proven, name
        assert lower_bound(problem) <= best.value * (1 + 1e-9) + 1e-9, name
        for m in METHODS:
            plan = solve(problem, m)
            assert plan.coverage_time >= best.value - 1e-6, (name, m)
            ratios[m].append(plan.coverage_time / best.value if best.value > 0 else 1.0)
    for m in METHODS:
        assert max(ratios[m]) <= WORST[m], (m, sorted(ratios[m])[-3:])


def test_alns_shares_a_viewpoint_where_the_optimum_does():
    """Seed 88: targets need two UAVs at two places, and the exact solver's optimal
    plan has both UAVs fly viewpoints 0 and 7. A search that gave each viewpoint to
    one UAV stayed 16 % above it; ALNS, allowed to share where two sightings are
    needed, reaches it, and the brute-force matching of `places_reference` counts
    the plan covered."""
    _, problem = optimality_case(88)
    best = optimum(problem)
    plan = solve(problem, "alns")
    flown = [v for route in plan.routes for v in set(route)]
    assert len(flown) > len(set(flown))
    assert ref.shortfall(problem, plan.routes) == 0
    assert plan.coverage_time == pytest.approx(best.value, rel=1e-9)


#: held-out instances of bench_coverage --optimal where ALNS without restarts stood
#: furthest above the optimum at the default budget (2026-11-29: seed 209 1.248,
#: 122 1.160, 125 1.125, 175 1.059); more budget alone did not help 122 (1.160 at
#: 0.5, 2 and 8 s)
BASINS = (122, 125, 175, 209)


@pytest.mark.parametrize("seed", BASINS)
def test_alns_restarts_leave_a_deep_basin(seed):
    _, problem = optimality_case(seed)
    best = optimum(problem)
    assert best.proven
    assert solve(problem, "alns").coverage_time <= 1.03 * best.value


def test_refuses_what_it_does_not_model():
    problem = random_problem(8, 40, 2, 0, seed=1, launch=True)
    problem.seen = np.zeros((2, 40), bool)
    with pytest.raises(ValueError, match="plain problems"):
        optimum(problem)
    problem.seen, problem.visited = None, np.zeros((2, 8), bool)
    with pytest.raises(ValueError, match="plain problems"):
        optimum(problem)
