"""A large area planned in parts (planner.split): the split, the owners of the
targets, the groups and the join, each against a brute-force reading of its rule."""

import numpy as np
import places_reference as ref
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from common.errors import InputError
from planner.coverage import CoverageProblem
from planner.split import (
    _shares,
    drop_redundant,
    group_sizes,
    make_parts,
    reach_bound,
    split_viewpoints,
)


@settings(max_examples=40, deadline=None)
@given(n=st.integers(1, 300), parts=st.integers(1, 7), seed=st.integers(0, 10_000))
def test_parts_are_balanced_and_do_not_overlap(n, parts, seed):
    xy = np.random.default_rng(seed).uniform(0, [5000, 2000], (n, 2)).round(-1)  # ties too
    labels = split_viewpoints(xy, parts)
    counts = np.bincount(labels, minlength=parts)
    assert counts.sum() == n and labels.max() < parts
    if n >= parts:
        assert counts.max() - counts.min() <= 1, counts
    # bisection boxes only touch: their areas add up to at most the whole box's
    boxes = [np.ptp(xy[labels == p], axis=0).prod() for p in range(parts) if counts[p]]
    assert sum(boxes) <= np.ptp(xy, axis=0).prod() + 1e-6


def _random_vis(rng, n_vp, n_t, density=0.2):
    rows = [np.flatnonzero(rng.random(n_t) < density) for _ in range(n_vp)]
    indptr = np.r_[0, np.cumsum([len(r) for r in rows])].astype(np.int64)
    indices = (np.concatenate(rows) if rows else np.zeros(0)).astype(np.int32)
    return indptr, indices


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 10_000), parts=st.integers(1, 4), need=st.integers(1, 3))
def test_each_target_owed_by_the_parts_with_most_viewpoints_seeing_it(seed, parts, need):
    """A part owes a target no more sightings than it has viewpoints seeing it (they
    must come from distinct places), the parts with most of them first, and all
    parts together owe what the whole area can give: min(need, viewpoints)."""
    rng = np.random.default_rng(seed)
    n_vp, n_t = 25, 40
    indptr, indices = _random_vis(rng, n_vp, n_t)
    labels = rng.integers(0, parts, n_vp)
    owed = _shares(indptr, indices, labels, np.full(n_t, need, np.int32), parts,
                   np.ones(len(indptr) - 1, bool))
    for t in range(n_t):
        seers = [e for e in range(n_vp) if t in indices[indptr[e]:indptr[e + 1]]]
        votes = np.bincount(labels[seers], minlength=parts) if seers else np.zeros(parts, int)
        assert (owed[t] <= votes).all() and owed[t].sum() == min(need, len(seers))
        # a part owes something only once every part with more viewpoints gives all it has
        for p in np.flatnonzero(owed[t]):
            assert all(owed[t, q] == votes[q] for q in range(parts) if votes[q] > votes[p])


def _problem(rng, n_uavs=4, k=1, n_vp=30, n_t=50, seen=False):
    indptr, indices = _random_vis(rng, n_vp, n_t, 0.15)
    out = rng.uniform(10, 100, (n_uavs, n_vp))
    saw = rng.random((n_uavs, n_t)) < 0.05 if seen else None
    return CoverageProblem(indptr, indices, n_t, None, out, out, n_uavs, k, seen=saw)


def _counts_by(problem, routes, arrivals, by):
    """Counted sightings of each target by ``by``: distinct UAVs at distinct places
    (brute force, `places_reference`)."""
    found = ref.sightings(problem, routes, arrivals)
    return np.array([ref.matched([f for f in found[t] if f[0] <= by])
                     for t in range(problem.n_targets)])


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10_000), k=st.integers(0, 2), seen=st.booleans())
def test_the_join_drops_only_what_coverage_does_not_need(seed, k, seen):
    rng = np.random.default_rng(seed)
    p = _problem(rng, k=k, seen=seen)
    routes = [list(rng.choice(p.n_viewpoints, rng.integers(0, 12), replace=False))
              for _ in range(p.n_uavs)]
    arrivals = [np.cumsum(rng.uniform(5, 50, len(r))) for r in routes]
    by = float(rng.uniform(50, 400))
    need = np.minimum(k + 1, _counts_by(p, routes, arrivals, by))
    keep = drop_redundant(p, routes, arrivals, by)
    assert [len(k) for k in keep] == [len(r) for r in routes]
    kept = [[e for e, k in zip(r, ks) if k] for r, ks in zip(routes, keep)]
    kept_at = [a[ks] for a, ks in zip(arrivals, keep)]
    assert (_counts_by(p, kept, kept_at, by) >= need).all()
    # and it is maximal: each kept visit by `by` is needed by some target
    for u, (r, a) in enumerate(zip(kept, kept_at)):
        for i in np.flatnonzero(np.asarray(a) <= by):
            less = [list(x) for x in kept]
            less_at = [np.asarray(x) for x in kept_at]
            del less[u][i]
            less_at[u] = np.delete(less_at[u], i)
            assert (_counts_by(p, less, less_at, by) < need).any()


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 10_000), k=st.integers(0, 2), seen=st.booleans())
def test_reach_bound_is_the_brute_force_one(seed, k, seen):
    rng = np.random.default_rng(seed)
    p = _problem(rng, k=k, seen=seen)
    first = np.full((p.n_uavs, p.n_targets), np.inf)
    for e in range(p.n_viewpoints):
        for t in p.vis_indices[p.vis_indptr[e]:p.vis_indptr[e + 1]]:
            first[:, t] = np.minimum(first[:, t], p.launch_out[:, e])
    if seen:
        first[p.seen] = 0.0
    need = ref.requirement(p)       # k + 1, at most one sighting per place seeing it
    kth = np.sort(first, axis=0)[np.maximum(need, 1) - 1, np.arange(p.n_targets)]
    kth = kth[need > 0]
    expected = kth[np.isfinite(kth)].max(initial=0.0)
    assert reach_bound(p) == pytest.approx(expected)


def test_groups_meet_every_part_s_need_and_use_the_whole_fleet():
    rng = np.random.default_rng(4)
    p = _problem(rng, n_uavs=7, k=1)
    parts = make_parts(p, rng.uniform(0, 1000, (p.n_viewpoints, 2)), 3)
    sizes = group_sizes(parts, 7, np.array([100.0, 0.0, 0.0]), 12.0)
    assert sizes.sum() == 7 and (sizes >= [part.need for part in parts]).all()
    # the parts together owe each target its k + 1 sightings, or one per viewpoint
    owed = np.zeros(p.n_targets, int)
    for part in parts:
        owed[part.targets] += part.required
    places = np.bincount(p.vis_indices, minlength=p.n_targets)
    assert (owed == np.minimum(p.k + 1, places)).all()
    with pytest.raises(InputError, match="--parts"):
        group_sizes(parts, 5, np.zeros(3), 12.0)
