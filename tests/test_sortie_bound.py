"""The sortie bound (`planner.coverage.bounds.sorties`, issue 63): under a battery no
plan covers the targets sooner. References: the optimum by enumeration of every
route set on small problems (the search's own sortie walk times each route), and a
star of far viewpoints whose optimum is known by hand (then the bound is exact)."""

import itertools
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planner.coverage import lower_bounds, prepare
from planner.coverage.bounds.sorties import sortie_bound
from planner.coverage.model.instances import random_problem
from planner.coverage.model.problem import CoverageProblem
from planner.coverage.model.routes import route_time


def _optimum(prep) -> float:
    """The least coverage time over every route set (k = 0: each required target
    seen once), each viewpoint flown by one UAV at most, each route timed by the
    search's sortie walk (`routes.route_time`, the greedy split)."""
    n, n_vp = prep.problem.n_uavs, prep.problem.n_viewpoints
    sees = [set(prep.vis_indices[prep.vis_indptr[e]:prep.vis_indptr[e + 1]].tolist())
            for e in range(n_vp)]
    needed = set(np.flatnonzero(prep.required > 0).tolist())
    fastest = {}

    def time_of(r, vps):
        if (r, vps) not in fastest:
            fastest[r, vps] = min((route_time(np.array(order, np.int64), prep.travel,
                                              prep.battery(r), True)
                                   for order in itertools.permutations(vps)), default=0.0)
        return fastest[r, vps]

    best = np.inf
    for owner in itertools.product(range(-1, n), repeat=n_vp):
        if not needed <= set().union(*(sees[e] for e in range(n_vp) if owner[e] >= 0)):
            continue
        routes = [tuple(e for e in range(n_vp) if owner[e] == r) for r in range(n)]
        best = min(best, max(time_of(r, vps) for r, vps in enumerate(routes)))
    return best


@settings(max_examples=30, deadline=None, derandomize=True)
@given(seed=st.integers(0, 10_000), n_uavs=st.integers(1, 2),
       reach=st.floats(1.05, 2.0), turnaround=st.floats(0.0, 300.0))
def test_no_route_set_covers_the_targets_sooner(seed, n_uavs, reach, turnaround):
    """Six viewpoints, a battery from just over the farthest round trip to twice
    it: the bound is at most the optimum found by enumeration."""
    problem = random_problem(n_viewpoints=6, n_targets=25, n_uavs=n_uavs, seed=seed,
                             launch=True, size_m=4000.0, sensor_m=900.0)
    trips = (problem.launch_out + problem.launch_back).min(axis=0)
    problem = replace(problem, endurance_s=float(trips.max()) * reach,
                      turnaround_s=turnaround)
    prep = prepare(problem)
    optimum = _optimum(prep)
    bound = sortie_bound(prep, problem.endurance_s)
    assert bound <= optimum + 1e-6, (bound, optimum)


def _star(n_uavs, arms=4, radius_s=100.0, turnaround_s=60.0):
    """Viewpoints on a circle round the base, ``radius_s`` out and back, each the
    only one to see its target; a battery of 1.2 round trips: no sortie sees two."""
    angle = 2 * np.pi * np.arange(arms) / arms
    xy = radius_s * np.column_stack([np.cos(angle), np.sin(angle)])
    travel = np.linalg.norm(xy[:, None] - xy[None], axis=2)
    out = np.full((n_uavs, arms), radius_s)
    return CoverageProblem(np.arange(arms + 1, dtype=np.int64), np.arange(arms, dtype=np.int32),
                           arms, travel, out, out.copy(), n_uavs,
                           endurance_s=2.4 * radius_s, turnaround_s=turnaround_s)


@pytest.mark.parametrize("n_uavs", [1, 2, 4])
def test_a_star_of_far_viewpoints_is_bound_exactly(n_uavs):
    """Each arm its own sortie: the busiest UAV flies ceil(4 / n) of them, all but
    its last home with a turnaround: (m - 1)(2r + T) + r, the optimum by hand and
    by enumeration. The bounds without the battery say far less."""
    problem = _star(n_uavs)
    m = -(-4 // n_uavs)
    by_hand = (m - 1) * (200.0 + 60.0) + 100.0
    prep = prepare(problem)
    assert _optimum(prep) == pytest.approx(by_hand)
    assert sortie_bound(prep, problem.endurance_s) == pytest.approx(by_hand)
    radius, best = lower_bounds(problem, True, prep)
    assert best == pytest.approx(by_hand)
    assert radius < by_hand or n_uavs == 4           # one arm each: no turnaround
    # a plan flies its sorties on the real battery: a search's scaled-down one
    # (`usable_s` larger) must not make the bound larger than the optimum there
    roomy = replace(problem, endurance_s=10 * 200.0)
    assert lower_bounds(problem, True, prep, usable_s=roomy.endurance_s)[1] <= \
        _optimum(prepare(roomy)) + 1e-9
