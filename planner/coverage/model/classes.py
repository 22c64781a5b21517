"""Target classes: cells seen by exactly the same viewpoints are interchangeable.

Two targets with the same set of viewpoints that see them, the same required
number of distinct UAVs and the same earlier sightings (re-planning) are
covered by exactly the same plans, at the same moment.  So coverage can be
decided per *class* of such targets, each weighted by how many cells it
holds: a plan covers every target iff it covers every class, and the number
of targets a visit gains is the summed weight of the classes it gains.  On
terrain there are far fewer classes than cells (neighbouring cells are seen
from the same places), so the bookkeeping of a search shrinks with them.

`target_classes` builds the class problem of a prepared problem, once (it is
kept on the problem: the search and the bounds of a plan share it); it is
exact (lists compared element by element, hashes only sort them).
"""

from dataclasses import replace

import numpy as np
from numba import njit

from .prepared import Prepared, csc_transpose


@njit(cache=True)
def _class_ids(order, t_indptr, t_indices, req, seen_key):
    """Walk targets in ``order`` (sorted by a key of their viewpoint lists) and
    start a new class whenever a target's list, need or sightings differ from
    the previous one's (exact comparison). Returns class id per target."""
    n = len(order)
    cls = np.empty(n, np.int64)
    c = -1
    prev = -1
    for i in range(n):
        t = order[i]
        same = prev >= 0 and req[t] == req[prev] and seen_key[t] == seen_key[prev]
        if same:
            a0, a1 = t_indptr[t], t_indptr[t + 1]
            b0, b1 = t_indptr[prev], t_indptr[prev + 1]
            if a1 - a0 != b1 - b0:
                same = False
            else:
                for j in range(a1 - a0):
                    if t_indices[a0 + j] != t_indices[b0 + j]:
                        same = False
                        break
        if not same:
            c += 1
        cls[t] = c
        prev = t
    return cls


@njit(cache=True)
def _gather_lists(indptr, indices, rows, out_indptr):
    """The lists of ``rows``, one after another (``out_indptr``: where each begins)."""
    out = np.empty(out_indptr[-1], np.int64)
    for i in range(len(rows)):
        a = indptr[rows[i]]
        for j in range(out_indptr[i + 1] - out_indptr[i]):
            out[out_indptr[i] + j] = indices[a + j]
    return out


@njit(cache=True)
def _set_hash(words, indptr, indices):
    """Sum (wrapping) of per-viewpoint random words over each target's list."""
    out = np.zeros(len(indptr) - 1, np.int64)
    for t in range(len(out)):
        for j in range(indptr[t], indptr[t + 1]):
            out[t] += words[indices[j]]
    return out


def target_classes(prep: Prepared):
    """(class problem, weight per class, class of each target), built once per
    prepared problem (`Prepared.classes_built`).

    The class problem is a `Prepared` whose targets are the classes: its
    visibility lists hold each class once, ``required`` and ``seen0`` are the
    members' (equal by construction).  Targets no viewpoint sees form classes
    too (kept so the counts line up; they need nothing)."""
    if prep.classes_built is None:
        prep.classes_built = _classes(prep)
    return prep.classes_built


def _classes(prep: Prepared):
    n_t = prep.problem.n_targets
    n_vp = prep.problem.n_viewpoints
    if n_t == 0:
        return prep, np.zeros(0, np.int64), np.zeros(0, np.int64)
    rng = np.random.default_rng(12345)
    h = rng.integers(1, 2**62, size=(2, max(n_vp, 1)), dtype=np.int64)
    deg = np.diff(prep.tgt_indptr)
    h1, h2 = (_set_hash(hv, prep.tgt_indptr, prep.tgt_indices) for hv in h)
    n = prep.seen0.shape[0]
    # earlier sightings as a key: bits of the UAVs that saw the target from a place
    # of its own (n < 63); those from viewpoints follow from the equal lists
    seen_key = (prep.own0.astype(np.int64) << np.arange(n, dtype=np.int64)[:, None]).sum(axis=0)
    order = np.lexsort((seen_key, prep.required, h2, h1, deg))
    cls = _class_ids(order, prep.tgt_indptr, prep.tgt_indices, prep.required, seen_key)
    n_c = int(cls.max()) + 1
    weight = np.bincount(cls, minlength=n_c).astype(np.int64)
    rep = np.empty(n_c, np.int64)
    rep[cls[order[::-1]]] = order[::-1]  # first member of each class (in walk order)
    # class CSC (class -> viewpoints) is the representative's list
    c_deg = deg[rep]
    c_indptr = np.zeros(n_c + 1, np.int64)
    np.cumsum(c_deg, out=c_indptr[1:])
    c_indices = _gather_lists(prep.tgt_indptr, prep.tgt_indices, rep, c_indptr)
    # class CSR (viewpoint -> classes): the transpose
    vis_indptr, vis_indices = csc_transpose(c_indptr, c_indices, n_vp)
    problem = replace(prep.problem, vis_indptr=vis_indptr, vis_indices=vis_indices,
                      n_targets=n_c, required=prep.required[rep].copy(),
                      seen=prep.own0[:, rep].astype(bool))
    out = replace(prep, problem=problem, vis_indptr=vis_indptr, vis_indices=vis_indices,
                  tgt_indptr=c_indptr, tgt_indices=c_indices.astype(np.int64),
                  seen0=np.ascontiguousarray(prep.seen0[:, rep]),
                  own0=np.ascontiguousarray(prep.own0[:, rep]),
                  required=prep.required[rep].astype(np.int32))
    return out, weight, cls
