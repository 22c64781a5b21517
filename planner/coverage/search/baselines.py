"""Baselines B and C of the paper, built strong so the comparison is honest.

* **B**: greedy dominating set first (a (k+1)-fold multicover for k > 0),
  then OR-Tools assigns and orders the chosen viewpoints over the UAVs with a
  makespan objective (clustering by time and routing in one model).
* **C**: time clustering of all viewpoints first (k-medoids on hidden travel
  time), each target to the cluster with most of its viewers, a dominating set
  per cluster, then one OR-Tools tour per cluster.

Neither construction knows that a target's k+1 sightings must come from
*distinct* UAVs, so afterwards any target still short is repaired with the RT
greedy (phases 2 and 3 from the current routes).  Finally the routing local
search of RT+LS runs with only its drop move (the repair may add redundant
visits): it relocates and swaps visits between routes and re-orders each
route, but never replaces a viewpoint by another, so the baselines get the
same routing effort as RT+LS while keeping their own selection.
"""

import numpy as np
from scipy.optimize import linear_sum_assignment

from .gains import CoverState
from .greedy import allocate
from .insertion import improve_route, insert_cost
from .local_search import local_search
from .routing import default_time_limit, route_nodes
from .setcover import dominating_set


def solve_b(prep, params):
    """Dominating set, clusters by time, a tour each, then OR-Tools on the whole fleet."""
    chosen = dominating_set(prep)
    n = prep.problem.n_uavs
    labels, medoids = cluster_viewpoints(prep, n, params.seed, nodes=chosen)
    owner = _assign_clusters(prep, chosen[medoids])
    initial = [[] for _ in range(n)]
    for c in range(len(medoids)):
        initial[owner[c]] = tour(prep, owner[c], chosen[labels == c])
    limit = params.routing_time_s or default_time_limit(len(chosen))
    routes = route_nodes(prep, chosen, list(range(n)), limit, initial=initial,
                         solution_limit=params.routing_solutions)
    return finish(prep, params, routes)


def solve_c(prep, params):
    """Time clusters of all viewpoints, then a dominating set and a tour per cluster."""
    n = prep.problem.n_uavs
    labels, medoids = cluster_viewpoints(prep, n, params.seed)
    owner = _assign_clusters(prep, medoids)  # cluster -> UAV
    target_cluster = _target_clusters(prep, labels, len(medoids))
    routes = [[] for _ in range(n)]
    for c in range(len(medoids)):
        need = (target_cluster == c).astype(np.int64)
        chosen = dominating_set(prep, need=need, allowed=labels == c)
        r = owner[c]
        limit = params.routing_time_s or default_time_limit(len(chosen))
        routes[r] = route_nodes(prep, chosen, [r], limit, initial=[tour(prep, r, chosen)],
                                solution_limit=params.routing_solutions)[0]
    return finish(prep, params, routes)


def tour(prep, r, nodes):
    """A short open tour of ``nodes`` for UAV r: cheapest insertion, then 2-opt / or-opt."""
    route = np.zeros(0, dtype=np.int64)
    for e in nodes:
        _, p = insert_cost(route, e, prep.travel, prep.battery(r), prep.has_launch)
        route = np.insert(route, p, e)
    return polish(prep, r, route)


def finish(prep, params, routes):
    """Repair distinct-UAV deficits with the RT greedy, then improve the routing.

    The routing local search (relocate / swap between routes, 2-opt / or-opt
    within) keeps the chosen viewpoints; it only strengthens the baseline.
    """
    state = state_of(prep, routes)
    if not state.done:
        routes, _ = allocate(prep, params, "ptv", routes=routes, state=state)
    return local_search(prep, routes, params.ls_rounds, select="drop")


def polish(prep, r, route):
    arr = np.asarray(route, dtype=np.int64)
    return list(map(int, improve_route(arr, prep.travel, prep.battery(r), prep.has_launch)))


def state_of(prep, routes) -> CoverState:
    state = CoverState(prep)
    for r, route in enumerate(routes):
        for e in route:
            state.take(e, r)
    return state


def symmetric_time(prep) -> np.ndarray:
    t = np.where(np.isfinite(prep.travel), prep.travel, 1e12)
    return 0.5 * (t + t.T)


def cluster_viewpoints(prep, n_clusters, seed, nodes=None, iterations=20):
    """k-medoids (alternating) on symmetric travel time; launch points seed it if given.

    Clusters ``nodes`` (default: all viewpoints); labels and medoids index into them.
    """
    d = symmetric_time(prep)
    if nodes is not None:
        d = d[np.ix_(nodes, nodes)]
    n_vp = d.shape[0]
    n_clusters = min(n_clusters, n_vp)
    if prep.has_launch:
        lo = prep.launch_out if nodes is None else prep.launch_out[:, nodes]
        medoids = _distinct_argmins(lo[:n_clusters])
    else:
        rng = np.random.default_rng(seed)
        medoids = [int(rng.integers(n_vp))]
        while len(medoids) < n_clusters:  # k-means++ seeding
            w = d[:, medoids].min(axis=1) ** 2
            medoids.append(int(rng.choice(n_vp, p=w / w.sum())) if w.sum() > 0
                           else int(rng.integers(n_vp)))
    medoids = np.asarray(medoids[:n_clusters])
    for _ in range(iterations):
        labels = np.argmin(d[:, medoids], axis=1)
        new = medoids.copy()
        for c in range(len(medoids)):
            members = np.flatnonzero(labels == c)
            if len(members):
                new[c] = members[np.argmin(d[np.ix_(members, members)].sum(axis=1))]
        if np.array_equal(new, medoids):
            break
        medoids = new
    return np.argmin(d[:, medoids], axis=1), medoids


def _distinct_argmins(launch_out):
    chosen = []
    for row in launch_out:
        order = np.argsort(row, kind="stable")
        chosen.append(int(next(e for e in order if e not in chosen)))
    return chosen


def _assign_clusters(prep, medoids):
    """Cluster -> UAV: nearest launch points (Hungarian), identity without launch."""
    n = prep.problem.n_uavs
    if not prep.has_launch:
        return list(range(n))
    rows, cols = linear_sum_assignment(np.nan_to_num(prep.launch_out[:, medoids].T, posinf=1e12))
    owner = [0] * len(medoids)
    for c, r in zip(rows, cols):
        owner[c] = int(r)
    return owner


def _target_clusters(prep, labels, n_clusters):
    """Each target goes to the cluster holding most of the viewpoints that see it."""
    n_t = prep.problem.n_targets
    votes = np.zeros((n_clusters, n_t), dtype=np.int64)
    for c in range(n_clusters):
        members = np.flatnonzero(labels == c)
        for e in members:
            votes[c, prep.vis_indices[prep.vis_indptr[e]:prep.vis_indptr[e + 1]]] += 1
    out = np.argmax(votes, axis=0)
    out[votes.max(axis=0) == 0] = -1
    return out
