"""Coverage methods on small synthetic problems, against independent references."""

import functools
import math
from dataclasses import replace

import numpy as np
import places_reference as ref
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planner.coverage import METHODS, CoverageProblem, coverage_counts, lower_bound, solve
from planner.coverage.model import CLOSED, FREE, achievable, beyond_battery, prepare
from planner.coverage.model.battery import Battery
from planner.coverage.model.instances import random_problem
from planner.coverage.model.routes import arrival_times, route_time
from planner.coverage.search.gains import CoverState
from planner.coverage.search.insertion import insert_cost, removal_saving

#: settings by name: each method takes those it has (the baselines' routing here)
FAST = {"routing_solutions": 20, "routing_time_s": 2.0}


def small(k=0, visibility="soft", launch=False, seed=0, n_uavs=3, family="uniform"):
    return random_problem(n_viewpoints=40, n_targets=300, n_uavs=n_uavs, k=k,
                          visibility=visibility, family=family, seed=seed, launch=launch,
                          size_m=2000.0, sensor_m=450.0)


@functools.lru_cache(maxsize=None)
def small_bound(**kwargs) -> float:
    """`lower_bound` of ``small(**kwargs)``, once per problem: every method is judged
    against the same one (the strong bound was most of these tests' time)."""
    return lower_bound(small(**kwargs))


# -- independent references ---------------------------------------------------

def ref_route_time(problem, r, route):
    if not route:
        return 0.0
    t = problem.launch_out[r, route[0]] if problem.launch_out is not None else 0.0
    return t + sum(problem.travel[a, b] for a, b in zip(route, route[1:]))


def required(problem):
    return ref.requirement(problem)


def assert_covers(problem, allocation):
    """Every target has its requirement of sightings from distinct UAVs at distinct
    places, and the planner counts them as the brute force does."""
    found = ref.sightings(problem, allocation.routes)
    need = required(problem)
    counts = [ref.matched(f) for f in found]
    assert all(c >= q for c, q in zip(counts, need))
    np.testing.assert_array_equal(coverage_counts(problem, allocation), counts)


def assert_times(problem, allocation):
    for r, route in enumerate(allocation.routes):
        t = ref_route_time(problem, r, route)
        assert allocation.times[r] == pytest.approx(t, abs=1e-6)
        back = t + (problem.launch_back[r, route[-1]]
                    if problem.launch_back is not None and route else 0.0)
        assert allocation.return_times[r] == pytest.approx(back, abs=1e-6)
    need = required(problem)
    cov = max((ref.needed_time(f, q) for f, q in zip(ref.sightings(problem, allocation.routes),
                                                      need)), default=0.0)
    assert allocation.coverage_time == pytest.approx(cov, abs=1e-6)
    assert allocation.mission_time == pytest.approx(max(allocation.return_times), abs=1e-6)


# -- every method ---------------------------------------------------------------

@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("k,visibility,launch", [
    (0, "soft", False), (1, "soft", True), (1, "hard", False), (2, "hard", True),
    (2, "soft", False)])
def test_methods_cover_with_consistent_times(method, k, visibility, launch):
    which = dict(k=k, visibility=visibility, launch=launch, seed=k + 3 * launch)
    problem = small(**which)
    a = solve(problem, method, FAST)
    assert a.covered and a.method == method
    assert_covers(problem, a)
    assert_times(problem, a)
    assert small_bound(**which) <= a.coverage_time + 1e-9


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("k", [0, 1])
def test_methods_plan_sorties_a_battery_can_fly(method, k):
    """With an endurance every method's routes, flown by the greedy split (the
    reference walk above), keep each sortie within one battery; the times it
    reports are the walk's, turnarounds included; a bound without the battery is
    still a bound (going home and out again is never quicker than flying on)."""
    which = dict(k=k, launch=True, seed=7 + k, n_uavs=3)
    problem = small(**which)
    unlimited = solve(problem, method, FAST)
    endurance = float((problem.launch_out + problem.launch_back).max()) * 1.6
    limited = replace(problem, endurance_s=endurance, turnaround_s=120.0)
    a = solve(limited, method, FAST)
    assert a.covered
    assert_covers(limited, a)
    several = 0
    for r, route in enumerate(a.routes):
        battery = _battery(problem.launch_out[r], problem.launch_out[r],
                           problem.launch_back[r], endurance, 120.0)
        arrive, flights = _reference_walk(route, problem.travel, battery)
        assert all(f <= endurance + 1e-9 for f in flights)
        assert a.times[r] == pytest.approx(arrive[-1] if route else 0.0, abs=1e-6)
        several += len(flights) > 1
    assert several                                  # the battery did split routes
    assert a.coverage_time >= unlimited.coverage_time * 0.9
    assert small_bound(**which) <= a.coverage_time + 1e-9


def test_viewpoints_beyond_one_battery_are_never_flown():
    problem = small(k=1, launch=True, seed=4, n_uavs=3)
    round_trip = problem.launch_out + problem.launch_back
    endurance = float(np.quantile(round_trip.min(axis=0), 0.8))
    limited = replace(problem, endurance_s=endurance, turnaround_s=60.0)
    far = beyond_battery(limited)
    # by definition: no UAV's base reaches them and back within the battery
    np.testing.assert_array_equal(far, np.flatnonzero(round_trip.min(axis=0) > endurance))
    assert len(far) >= 4
    for method in ("rt", "alns"):
        a = solve(limited, method, FAST)
        assert not set(far) & {e for r in a.routes for e in r}
        # what the rest can still see is covered; targets only they saw are counted
        counts = coverage_counts(limited, a)
        need = np.minimum(limited.needs(), achievable(limited))
        assert np.all(counts >= need)
        assert a.uncoverable == int(np.count_nonzero(limited.needs() > achievable(limited)))
    assert a.uncoverable > solve(problem, "alns", FAST).uncoverable


@pytest.mark.parametrize("method", METHODS)
def test_deterministic_for_fixed_seed(method):
    problem = small(k=1, launch=True, seed=5, family="clustered")
    a = solve(problem, method, FAST)
    b = solve(problem, method, FAST)
    assert a.routes == b.routes


def test_k_not_below_fleet_size_is_an_error():
    with pytest.raises(ValueError, match="k=3 needs at least k\\+1=4 UAVs"):
        solve(small(k=3, n_uavs=3), "rt")
    with pytest.raises(ValueError, match="unknown coverage method"):
        solve(small(), "xx")


def test_rt_ls_never_worse_than_rt_and_keeps_coverage():
    for seed in range(4):
        for k in (0, 1):
            problem = small(k=k, seed=seed, launch=bool(seed % 2), family="corridor")
            rt = solve(problem, "rt")
            ls = solve(problem, "rt+ls")
            assert ls.coverage_time <= rt.coverage_time + 1e-9
            assert_covers(problem, ls)


# -- the paper's properties ------------------------------------------------------

def unseen_after_starts(problem, steps):
    """k = 0: per viewpoint, targets no start has seen (independent of the gain code)."""
    seen = np.zeros(problem.n_targets, dtype=bool)
    for phase, _, e, _ in steps:
        if phase == 1:
            seen[problem.vis_indices[problem.vis_indptr[e]:problem.vis_indptr[e + 1]]] = True
    return np.array([np.count_nonzero(~seen[problem.vis_indices[
        problem.vis_indptr[e]:problem.vis_indptr[e + 1]]])
        for e in range(problem.n_viewpoints)])


@pytest.mark.parametrize("seed", range(3))
def test_alpha_one_picks_most_visible_alpha_zero_picks_quickest(seed):
    problem = small(seed=seed)
    n = problem.n_uavs
    a1 = solve(problem, "rt", {"alpha": 1.0, "step_time_cap": math.inf})
    v = unseen_after_starts(problem, a1.steps)
    phase, _, e, _ = a1.steps[n]
    assert phase == 2 and v[e] == v.max()

    a0 = solve(problem, "rt", {"alpha": 0.0, "step_time_cap": math.inf})
    v = unseen_after_starts(problem, a0.steps)
    starts = [e for phase, _, e, _ in a0.steps[:n]]
    # routes are single starts with time 0: the pick minimises the insertion time
    quickest = min(min(problem.travel[e, s], problem.travel[s, e])
                   for s in starts for e in np.flatnonzero(v > 0))
    phase, r, e, _ = a0.steps[n]
    s = starts[r]
    assert phase == 2 and min(problem.travel[e, s], problem.travel[s, e]) == pytest.approx(
        quickest)


def mean_spread(problem, steps):
    """Mean of (max - min) / max of the UAV times over the allocation, once all have started."""
    times = np.zeros(problem.n_uavs)
    started = np.zeros(problem.n_uavs, dtype=bool)
    spreads = []
    for _, r, _, t in steps:
        times[r], started[r] = t, True
        if started.all() and times.max() > 0:
            spreads.append((times.max() - times.min()) / times.max())
    return np.mean(spreads)


def test_threshold_adaptation_keeps_uav_times_together():
    with_, without = [], []
    for seed in range(4):
        for family in ("uniform", "clustered"):
            problem = random_problem(80, 800, 4, seed=seed, family=family,
                                     launch=bool(seed % 2))
            a = solve(problem, "rt")
            b = solve(problem, "rt", {"threshold_adaptation": False})
            assert any(s[0] == 3 for s in a.steps) and not any(s[0] == 3 for s in b.steps)
            for alloc in (a, b):  # the recorded times are the routes' real times
                last = {r: t for _, r, _, t in alloc.steps}
                for r, t in last.items():
                    assert t == pytest.approx(ref_route_time(problem, r, alloc.routes[r]))
            with_.append(mean_spread(problem, a.steps))
            without.append(mean_spread(problem, b.steps))
    assert np.mean(with_) < 0.8 * np.mean(without)


def test_phase_one_spreads_out_starts():
    problem = small(seed=2)
    a = solve(problem, "rt")
    starts = [e for phase, _, e, _ in a.steps if phase == 1]
    assert len(starts) == problem.n_uavs
    v = unseen_after_starts(problem, [])
    assert v[starts[0]] == v.max()  # the first start is the most visible viewpoint


# -- pieces -----------------------------------------------------------------------

@given(st.integers(0, 2 ** 16), st.integers(0, 6), st.booleans())
@settings(max_examples=30, deadline=None)
def test_edge_breaking_insertion_is_cheapest_position(seed, length, launch):
    rng = np.random.default_rng(seed)
    n = 10
    travel = rng.uniform(1, 10, (n, n))
    lo = rng.uniform(1, 10, n)
    battery = _battery(lo, lo, rng.uniform(1, 10, n))      # no limit
    route = rng.permutation(n)[:length].astype(np.int64)
    e = int(rng.permutation(np.setdiff1d(np.arange(n), route))[0])
    base = route_time(route, travel, battery, launch)
    brute = min(route_time(np.insert(route, p, e), travel, battery, launch) - base
                for p in range(length + 1))
    cost, pos = insert_cost(route, e, travel, battery, launch)
    assert cost == pytest.approx(brute)
    assert route_time(np.insert(route, pos, e), travel, battery, launch) - base \
        == pytest.approx(brute)


def _battery(out, base_out, back, endurance=np.inf, turnaround=0.0, used=0.0,
             start_back=0.0) -> Battery:
    """One UAV's `Battery` with its own base only (no bases listed)."""
    n = len(out)
    return Battery(np.asarray(out, float), np.asarray(base_out, float), np.asarray(back, float),
                   np.zeros(n, np.int64), np.zeros((0, n)), float(endurance), float(turnaround),
                   float(used), float(start_back))


def _metric_sorties(seed, n=12):
    """Viewpoints and a base in the plane (travel is distance: the triangle
    inequality holds, as for shortest hidden paths), a battery that flies 1-3 of
    them, a UAV that starts at its base with part of its battery flown."""
    rng = np.random.default_rng(seed)
    xy = rng.uniform(0, 100, (n, 2))
    travel = np.hypot(*(xy[:, None] - xy[None]).transpose(2, 0, 1))
    home = np.hypot(*xy.T)
    out, base_out, back = home, home + 5.0, home + 3.0     # a climb out, a landing back
    endurance = float((base_out + back).max() + rng.uniform(0, 150))
    turnaround, used = rng.uniform(0, 50), rng.uniform(0, 0.3) * endurance
    return rng, travel, _battery(out, base_out, back, endurance, turnaround, used, 3.0)


def _reference_walk(route, travel, b):
    """The greedy split by its definition: fly on while the next viewpoint and the
    way home from it fit the battery ``b``; else home, turnaround, a new battery."""
    t, flown, sorties, arrive = 0.0, b.used, [[]], []
    for i, e in enumerate(route):
        out = b.out[e] if i == 0 else travel[route[i - 1], e]
        home = b.start_back if i == 0 else b.back[route[i - 1]]
        if flown + out + b.back[e] > b.endurance:
            t, flown = t + home + b.turnaround + b.base_out[e], b.base_out[e]
            sorties.append([])
        else:
            t, flown = t + out, flown + out
        arrive.append(t)
        sorties[-1].append(flown + b.back[e])
    return arrive, [max(s) for s in sorties if s]


@given(st.integers(0, 2 ** 16), st.integers(0, 10))
@settings(max_examples=40, deadline=None)
def test_sorties_fit_the_battery_and_insertion_costs_are_exact(seed, length):
    rng, travel, battery = _metric_sorties(seed)
    route = rng.permutation(len(travel))[:length].astype(np.int64)
    arrive, flights = _reference_walk(route, travel, battery)
    np.testing.assert_allclose(arrival_times(route, travel, battery, True), arrive)
    assert all(f <= battery.endurance + 1e-9 for f in flights)   # each within one battery
    base = route_time(route, travel, battery, True)
    e = int(rng.permutation(np.setdiff1d(np.arange(len(travel)), route))[0])
    cost, pos = insert_cost(route, e, travel, battery, True)
    # the rule's cost is the walked route's own, and no insertion is dearer than
    # opening a sortie of its own at the end
    assert route_time(np.insert(route, pos, e), travel, battery, True) - base \
        == pytest.approx(cost, abs=1e-9)
    assert cost <= route_time(np.append(route, e), travel, battery, True) - base + 1e-9
    if length:
        i = int(rng.integers(length))
        assert removal_saving(route, i, travel, battery, True) == pytest.approx(
            base - route_time(np.delete(route, i), travel, battery, True))


def _two_base_problem(seed, n=12, n_bases=3):
    """`_metric_sorties`'s plane with ``n_bases`` bases a sortie may land at (the
    UAV's own the first), as a one-UAV `CoverageProblem` and its prepared battery."""
    rng, travel, one = _metric_sorties(seed, n)
    xy = np.random.default_rng(seed + 1).uniform(0, 100, (n, 2))
    travel = np.hypot(*(xy[:, None] - xy[None]).transpose(2, 0, 1))
    bases = np.vstack([[0.0, 0.0], rng.uniform(0, 100, (n_bases - 1, 2))])
    dist = np.hypot(*(xy[None] - bases[:, None]).transpose(2, 0, 1))    # [base, viewpoint]
    out, back = dist + 5.0, dist + 3.0
    # every base reaches every viewpoint and home (`test_a_sortie_lands_at_another_base_
    # to_reach_what_its_own_cannot` has those that cannot)
    endurance = float((out + back.min(axis=0)).max() + rng.uniform(0, 150))
    used = one.used * endurance / one.endurance
    problem = CoverageProblem(np.zeros(n + 1, np.int64), np.zeros(0, np.int64), 0, travel,
                              out[:1], back[:1], 1, endurance_s=endurance,
                              turnaround_s=one.turnaround, used_s=np.array([used]),
                              start_back=np.array([3.0]), bases_out=out, bases_back=back)
    return rng, problem, prepare(problem).battery(0)


def _reference_walk_bases(route, problem, b):
    """The greedy split by its definition, with several bases: fly on while the next
    viewpoint and the way home to the nearest base fit the battery; else land at
    the base nearest the last viewpoint, a turnaround and a new battery there, and
    out from it (a base that cannot reach a viewpoint and home again on one
    battery does not fly there: inf). Returns the arrivals, each sortie's flight
    and the base each lands at (of the battery ``b`` only its numbers are read:
    endurance, turnaround, used and the start's way home)."""
    out, back_to = np.asarray(problem.bases_out), np.asarray(problem.bases_back)
    back, at = back_to.min(axis=0), back_to.argmin(axis=0)
    leaves = np.where(out + back > b.endurance, np.inf, out)
    t, flown, arrive, sorties, lands = 0.0, b.used, [], [[]], []
    for i, e in enumerate(route):
        step = leaves[0, e] if i == 0 else problem.travel[route[i - 1], e]
        home = b.start_back if i == 0 else back[route[i - 1]]
        if flown + step + back[e] > b.endurance:
            base = 0 if i == 0 else at[route[i - 1]]
            lands.append(base)
            t, flown = t + home + b.turnaround + leaves[base, e], leaves[base, e]
            sorties.append([])
        else:
            t, flown = t + step, flown + step
        arrive.append(t)
        sorties[-1].append(flown + back[e])
    return arrive, [max(f) for f in sorties if f], lands + [at[route[-1]]] * bool(len(route))


@given(st.integers(0, 2 ** 16), st.integers(1, 10))
@settings(max_examples=40, deadline=None)
def test_sorties_land_at_the_nearest_base_and_leave_from_it(seed, length):
    """Several bases: the kernels' walk is the split by its definition (each sortie
    lands at the base nearest its last viewpoint, the next leaves from there),
    every sortie fits the battery, an insertion's cost is never below what the
    walked route then takes, and a removal saves what the walks say."""
    rng, problem, battery = _two_base_problem(seed)
    travel = problem.travel
    route = rng.permutation(len(travel))[:length].astype(np.int64)
    arrive, flights, _ = _reference_walk_bases(route, problem, battery)
    np.testing.assert_allclose(arrival_times(route, travel, battery, True), arrive)
    assert all(f <= battery.endurance + 1e-9 for f in flights)
    base = route_time(route, travel, battery, True)
    e = int(rng.permutation(np.setdiff1d(np.arange(len(travel)), route))[0])
    cost, _ = insert_cost(route, e, travel, battery, True)
    assert np.isfinite(base) and np.isfinite(cost)
    # opening a sortie of its own at the end is always an offer, and walked as costed
    end = route_time(np.append(route, e), travel, battery, True) - base
    assert cost <= end + 1e-9
    i = int(rng.integers(length))
    assert removal_saving(route, i, travel, battery, True) == pytest.approx(
        base - route_time(np.delete(route, i), travel, battery, True))


def test_a_sortie_lands_at_another_base_to_reach_what_its_own_cannot():
    """Viewpoints on a line from base A (x = 0) to base B (x = 1000): one UAV at A
    whose battery does not take it to the far end and back, but does to the far
    end and on to B. Landing at its own base only, the far viewpoints are beyond
    its battery; with both bases, it lands at B once and covers them all."""
    x = np.linspace(100.0, 900.0, 9)
    travel = np.abs(x[:, None] - x[None])
    out = np.stack([x, 1000.0 - x]) + 10.0          # climbs out of A and of B
    back = np.stack([x, 1000.0 - x]) + 8.0          # back to each, landings included
    indptr, indices = np.arange(10, dtype=np.int64), np.arange(9, dtype=np.int32)
    endurance = 1300.0          # A -> 900 -> A: 1818; A -> 900 -> B: 1018
    own = CoverageProblem(indptr, indices, 9, travel, out[:1], back[:1], 1,
                          endurance_s=endurance, turnaround_s=60.0)
    both = replace(own, bases_out=out, bases_back=back)
    assert set(beyond_battery(own)) == {6, 7, 8} and len(beyond_battery(both)) == 0
    # with less battery no sortie out of A lands at B, and what only B reaches is
    # as far as without it: a base nobody comes to is no start
    assert set(beyond_battery(replace(both, endurance_s=1000.0))) == {4, 5, 6, 7, 8}
    for method in METHODS:
        a = solve(both, method, FAST)
        assert a.covered, method
        battery = _battery(out[0], out[0], back[0], endurance, 60.0)   # its numbers only
        route = np.asarray(a.routes[0], np.int64)
        arrive, flights, lands = _reference_walk_bases(route, both, battery)
        assert all(f <= endurance + 1e-9 for f in flights), method
        assert 1 in lands, method                     # it lands at B
        assert a.times[0] == pytest.approx(arrive[-1]), method
        assert solve(own, method, FAST).uncoverable == 3, method


@given(st.integers(0, 2 ** 16))
@settings(max_examples=60, deadline=None)
def test_a_targets_sightings_count_only_uavs_that_can_reach_a_viewpoint_of_it(seed):
    """`_achievable` against brute force: the most distinct UAVs that can sight a
    target, each from a place of its own (an earlier sighting) or a viewpoint of
    it that it can fly (within its battery) and no other of them takes."""
    from itertools import product

    # the kernel itself (private): `achievable` derives ``able`` from a problem's
    # battery, where this test draws it at random
    from planner.coverage.model.prepared import _achievable, csc_transpose

    rng = np.random.default_rng(seed)
    n, n_vp, n_t = int(rng.integers(1, 5)), int(rng.integers(1, 6)), 6
    sees = rng.random((n_vp, n_t)) < 0.5
    able = rng.random((n, n_vp)) < rng.uniform(0.2, 1.0)
    own = rng.random((n, n_t)) < 0.15
    owner = np.where(rng.random(n_vp) < 0.2, CLOSED, FREE).astype(np.int64)
    indptr = np.r_[0, np.cumsum(sees.sum(axis=1))].astype(np.int64)
    tgt_indptr, tgt_indices = csc_transpose(indptr, np.nonzero(sees)[1].astype(np.int32), n_t)
    got = _achievable(tgt_indptr, tgt_indices, owner, own, n, able)
    for t in range(n_t):
        vps = [e for e in range(n_vp) if sees[e, t] and owner[e] != CLOSED]
        best = 0                    # every choice of one viewpoint (or none) per UAV
        for pick in product([None, *vps], repeat=n):
            flown = [e for r, e in enumerate(pick) if e is not None and not own[r, t]]
            if all(e is None or (able[r, e] and not own[r, t]) for r, e in enumerate(pick)) \
                    and len(set(flown)) == len(flown):
                best = max(best, int(own[:, t].sum()) + len(flown))
        assert got[t] == best, (t, got[t], best)


@pytest.mark.parametrize("visibility", ["hard", "soft"])
def test_incremental_gains_match_recomputation(visibility):
    problem = small(k=2, visibility=visibility, seed=4, n_uavs=4)
    prep = prepare(problem)
    state = CoverState(prep)
    rng = np.random.default_rng(0)
    for _ in range(60):
        state.take(int(rng.integers(problem.n_viewpoints)), int(rng.integers(4)))
    count = state.seen.sum(axis=0)
    expo = 4 / 2
    for e in range(0, problem.n_viewpoints, 3):
        for r in range(4):
            want = 0.0
            for t in problem.vis_indices[problem.vis_indptr[e]:problem.vis_indptr[e + 1]]:
                need = min(3, ref.achievable(problem)[t])   # k + 1, or what it can get
                if state.seen[r, t] or count[t] >= need:
                    continue
                want += (need - count[t]) ** expo if visibility == "soft" else 1.0
            assert state.gains[e, r] == pytest.approx(want)
    assert state.remaining == np.count_nonzero(count < np.minimum(3, ref.achievable(problem)))


@given(st.integers(0, 2 ** 16), st.integers(0, 1), st.booleans())
@settings(max_examples=20, deadline=None)
def test_random_structures_are_covered(seed, k, launch):
    """Arbitrary visibility sets and asymmetric (non-metric) travel times."""
    rng = np.random.default_rng(seed)
    n_vp, n_t, n = int(rng.integers(3, 15)), int(rng.integers(1, 40)), 2
    sets = [np.union1d(rng.choice(n_t, rng.integers(1, n_t + 1), replace=False),
                       np.arange(e, n_t, n_vp)) for e in range(n_vp)]  # every target seen
    indptr = np.concatenate([[0], np.cumsum([len(s) for s in sets])])
    travel = rng.uniform(1, 20, (n_vp, n_vp))
    np.fill_diagonal(travel, 0)
    lo = rng.uniform(1, 20, (n, n_vp)) if launch else None
    problem = CoverageProblem(indptr, np.concatenate(sets), n_t, travel, lo, lo, n, k,
                              "soft")
    bound = lower_bound(problem)
    for method in ("rt", "rt+ls", "rd"):
        a = solve(problem, method)
        assert a.covered
        assert_covers(problem, a)
        assert_times(problem, a)
        assert bound <= a.coverage_time + 1e-9


def test_unseeable_targets_are_reported_not_chased():
    travel = np.array([[0.0, 5.0], [5.0, 0.0]])
    problem = CoverageProblem(np.array([0, 1, 2]), np.array([0, 1]), 3, travel, None, None, 2)
    a = solve(problem, "rt")
    assert a.uncoverable == 1 and a.covered
    assert sorted(e for route in a.routes for e in route) == [0, 1]


def test_replanning_counts_earlier_snapshots():
    problem = small(k=1, seed=6, launch=True)
    rng = np.random.default_rng(1)
    problem.seen = rng.uniform(size=(problem.n_uavs, problem.n_targets)) < 0.4
    need = np.full(problem.n_targets, 2)
    need[::5] = 1  # a lost UAV's share: reduced needs
    problem.required = need
    for method in METHODS:
        a = solve(problem, method, FAST)
        assert_covers(problem, a)
        assert_times(problem, a)
    # nothing left to do: empty routes, zero coverage time
    problem.seen = np.ones((problem.n_uavs, problem.n_targets), dtype=bool)
    a = solve(problem, "rt")
    assert a.routes == [[], [], []] and a.coverage_time == 0.0


@pytest.mark.parametrize("k", [1, 2])
def test_replanning_counts_earlier_photographs_at_their_viewpoints(k):
    """Earlier photographs from viewpoints (some by two UAVs) are sightings at those
    places: a UAV flying one of them again adds no place, and another UAV may fly
    it where only that gives a target its sightings. Judged by the brute-force
    matching over places, every method."""
    problem = small(k=k, seed=7, launch=True)
    rng = np.random.default_rng(3)
    problem.visited = rng.uniform(size=(problem.n_uavs, problem.n_viewpoints)) < 0.12
    problem.seen = rng.uniform(size=(problem.n_uavs, problem.n_targets)) < 0.05
    assert (problem.visited.sum(axis=0) >= 2).any()
    for method in METHODS:
        a = solve(problem, method, FAST)
        assert a.covered, method
        assert_covers(problem, a)
        assert_times(problem, a)


def test_a_place_one_uav_took_is_flown_by_another_when_the_target_needs_it():
    """`make demo`'s lost target: seen only from viewpoints 0 and 1, both of which
    UAV 0 photographed from before; k = 1 needs UAV 1 at one of them, whatever the
    method (ALNS: at the nearer for it, 1, while UAV 0 flies 2: the optimum)."""
    travel = np.array([[0.0, 60.0, 30.0], [60.0, 0.0, 30.0], [30.0, 30.0, 0.0]])
    lo = np.array([[10.0, 10.0, 10.0], [40.0, 20.0, 5.0]])
    problem = CoverageProblem(np.array([0, 1, 2, 3]), np.array([0, 0, 1]), 2, travel, lo, lo,
                              2, k=1, visited=np.array([[True, True, False], [False] * 3]))
    for method in METHODS:
        a = solve(problem, method, FAST)
        assert a.covered and a.uncoverable == 1, method     # target 1: one place
        assert 1 in a.routes[1] or 0 in a.routes[1], method
        assert_covers(problem, a)
        assert_times(problem, a)
    a = solve(problem, "alns", FAST)
    assert a.routes == [[2], [1]] and a.coverage_time == pytest.approx(20.0)


def test_lower_bound_reach_term_with_launch_points():
    """One target: the bound is the (k+1)-th fastest UAV to reach a place seeing it.
    Seen only from viewpoint 1 it has one place, so one sighting counts, k or not;
    seen from both, its two sightings come from two UAVs at the two places."""
    travel = np.array([[0.0, 60.0], [60.0, 0.0]])
    lo = np.array([[10.0, 30.0], [15.0, 20.0], [50.0, 40.0]])
    one = CoverageProblem(np.array([0, 0, 1]), np.array([0]), 1, travel, lo, lo, 3, k=1)
    assert lower_bound(one) == pytest.approx(20.0)
    assert solve(one, "rt").coverage_time == pytest.approx(20.0)
    both = CoverageProblem(np.array([0, 1, 2]), np.array([0, 0]), 1, travel, lo, lo, 3, k=1)
    assert lower_bound(both) == pytest.approx(20.0)    # matched over places: the optimum
    for method in METHODS:   # the optimum: UAV 1 at viewpoint 0 (10 s), UAV 2 at 1 (20 s)
        a = solve(both, method, FAST)
        assert a.coverage_time == pytest.approx(20.0), method
        assert sorted(map(tuple, a.routes)) == [(), (0,), (1,)]
