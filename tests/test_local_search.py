"""The local search's drop move (RT+LS, and the start of ALNS) against the plain
rule it implements: on each route, longest first, drop the visit that saves the
most time among those coverage can spare, and again, until none can be dropped.
The reference counts coverage from the routes each time (distinct UAVs per
target, what was seen before included), nothing kept between drops."""

from dataclasses import replace

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from planner.coverage.model import prepare
from planner.coverage.model.instances import random_problem
from planner.coverage.model.routes import route_time
from planner.coverage.search.insertion import improve_route, removal_saving, removal_savings
from planner.coverage.search.local_search import Search


def _problem(seed, k, battery):
    problem = random_problem(n_viewpoints=30, n_targets=200, n_uavs=3, k=k, seed=seed,
                             launch=True, size_m=2000.0, sensor_m=600.0)
    if battery:  # sorties: room for a few viewpoints per battery
        problem = replace(problem, endurance_s=2.5 * float(
            (problem.launch_out + problem.launch_back).max()))
    return problem


def _covered(prep, routes, t_of):
    """Whether each target in ``t_of`` is seen by as many distinct UAVs as it needs."""
    seen = prep.seen0.astype(bool)
    for r, route in enumerate(routes):
        for e in route:
            seen[r, prep.vis_indices[prep.vis_indptr[e]:prep.vis_indptr[e + 1]]] = True
    return bool((seen[:, t_of].sum(axis=0) >= prep.required[t_of]).all())


def _reference_drops(prep, routes):
    routes = [np.asarray(r, np.int64) for r in routes]
    bats = [prep.battery(r) for r in range(len(routes))]
    times = [route_time(rt, prep.travel, bats[r], prep.has_launch) for r, rt in enumerate(routes)]
    for r in np.argsort(-np.array(times), kind="stable"):
        dropped = True
        while dropped and len(routes[r]):
            dropped = False
            route = routes[r]
            savings = np.array([removal_saving(route, i, prep.travel, bats[r], prep.has_launch)
                                for i in range(len(route))])
            for i in np.argsort(-savings, kind="stable"):
                if savings[i] < -1e-6:
                    break
                e = route[i]
                trial = list(routes)
                trial[r] = np.delete(route, i)
                if _covered(prep, trial, prep.vis_indices[prep.vis_indptr[e]:
                                                          prep.vis_indptr[e + 1]]):
                    routes, dropped = trial, True
                    break
    return routes


@settings(max_examples=25, deadline=None, derandomize=True)
@given(seed=st.integers(0, 10_000), k=st.integers(0, 1), battery=st.booleans(),
       share=st.floats(0.3, 0.9))
def test_drops_are_the_plain_rule(seed, k, battery, share):
    """Random routes that see most targets several times over: the same visits
    dropped, in the same order, as the plain rule; and every saving of a route in
    one call is the saving of that visit alone."""
    prep = prepare(_problem(seed, k, battery))
    rng = np.random.default_rng(seed)
    n_vp = len(prep.vis_indptr) - 1
    routes = [rng.permutation(np.flatnonzero(rng.random(n_vp) < share)) for _ in range(3)]
    search = Search(prep, routes, select="drop")
    search.drop_redundant()
    expected = _reference_drops(prep, routes)
    assert [list(r) for r in search.routes] == [list(r) for r in expected]
    for r, route in enumerate(routes):
        bat = prep.battery(r)
        assert list(removal_savings(route, prep.travel, bat, prep.has_launch)) == [
            removal_saving(route, i, prep.travel, bat, prep.has_launch)
            for i in range(len(route))]


def test_inputs_in_any_layout_reach_the_kernels_in_one():
    """A problem whose arrays come transposed (as a part's do) or with other index
    and flag types plans with the kernels already compiled for the usual ones: no
    second compilation (seconds to a minute each, on a user's first plan in parts)."""
    from planner.coverage import coverage_counts, solve
    from planner.coverage.model.routes import walked
    from planner.coverage.search.alns_kernels import repair

    problem = _problem(7, 1, battery=True)
    usual = solve(problem, "alns", {"time_budget_s": 0.3})
    coverage_counts(problem, usual)
    compiled = {f: len(f.signatures) for f in (route_time, walked, repair)}
    other = replace(problem, launch_out=np.asfortranarray(problem.launch_out),
                    launch_back=np.asfortranarray(problem.launch_back),
                    vis_indices=problem.vis_indices.astype(np.int64),
                    seen=np.zeros((problem.n_uavs, problem.n_targets), bool))
    again = solve(other, "alns", {"time_budget_s": 0.3})
    coverage_counts(other, again)
    assert again.routes == usual.routes
    assert {f: len(f.signatures) for f in compiled} == compiled


def _reference_improve(route, travel, battery, has_launch):
    """2-opt, then or-opt of segments of 1-3 (also reversed), every candidate summed
    by `route_time`, until none improves."""
    best = np.asarray(route, np.int64)
    best_t = route_time(best, travel, battery, has_launch)
    m, improved = len(best), True
    while improved:
        improved = False
        for i in range(m - 1):
            for j in range(i + 1, m):
                cand = np.concatenate((best[:i], best[i:j + 1][::-1], best[j + 1:]))
                t = route_time(cand, travel, battery, has_launch)
                if t < best_t - 1e-9:
                    best, best_t, improved = cand, t, True
        for seg in range(1, 4):
            for i in range(m - seg + 1):
                segment, rest = best[i:i + seg], np.concatenate((best[:i], best[i + seg:]))
                moved = False
                for s in (segment, segment[::-1]):
                    for p in range(len(rest) + 1):
                        if p == i and s is segment:
                            continue
                        cand = np.concatenate((rest[:p], s, rest[p:]))
                        t = route_time(cand, travel, battery, has_launch)
                        if t < best_t - 1e-9:
                            best, best_t, improved, moved = cand, t, True, True
                            break
                    if moved:
                        break
    return best


@settings(max_examples=30, deadline=None, derandomize=True)
@given(seed=st.integers(0, 10_000), length=st.integers(1, 14), launch=st.booleans(),
       battery=st.booleans())
def test_route_improvement_makes_the_moves_of_summing_every_candidate(seed, length, launch,
                                                                       battery):
    """Without sorties the candidates are estimated first and only the promising ones
    summed: the same route as summing them all (asymmetric travel: climbs and
    descents differ), with sorties the same as well."""
    problem = _problem(seed, 0, battery and launch)
    if not launch:
        problem = replace(problem, launch_out=None, launch_back=None)
    prep = prepare(problem)
    route = np.random.default_rng(seed).permutation(len(prep.vis_indptr) - 1)[:length]
    bat = prep.battery(0)
    assert list(improve_route(route, prep.travel, bat, prep.has_launch)) == list(
        _reference_improve(route, prep.travel, bat, prep.has_launch))
