"""Min-makespan routing of a fixed set of viewpoints with OR-Tools.

Open routes: without launch points a vehicle starts at whichever viewpoint
suits it (a free dummy depot); with launch points vehicle r starts at its own
launch node (cost ``launch_out[r]``).  Routes end at a free dummy node, since
coverage time stops at the last snapshot.  The objective is a global span
cost on the time dimension (the makespan) plus the summed time as a
tie-break; guided local search runs for a bounded time.
"""

import numpy as np
from ortools.constraint_solver import pywrapcp, routing_enums_pb2

_SCALE = 1000.0  # integer milliseconds for the solver
FORBIDDEN = 10 ** 9  # unreachable / forbidden arcs
SPAN_WEIGHT = 100


def transit_matrix(prep, nodes, uavs):
    """Integer transit matrix: viewpoints, then start nodes, then one end node."""
    m, n_v = len(nodes), len(uavs)
    has_launch = prep.has_launch
    n_start = n_v if has_launch else 1
    size = m + n_start + 1
    end = size - 1
    mat = np.full((size, size), FORBIDDEN, dtype=np.int64)
    sub = prep.travel[np.ix_(nodes, nodes)] * _SCALE
    mat[:m, :m] = np.where(np.isfinite(sub), np.minimum(np.round(sub), FORBIDDEN), FORBIDDEN)
    for s in range(n_start):
        if has_launch:
            out = prep.launch_out[uavs[s], nodes] * _SCALE
            mat[m + s, :m] = np.where(np.isfinite(out), np.minimum(np.round(out), FORBIDDEN),
                                      FORBIDDEN)
        else:
            mat[m + s, :m] = 0
        mat[m + s, end] = 0
    mat[:m, end] = 0
    np.fill_diagonal(mat, 0)
    starts = [m + (i if has_launch else 0) for i in range(n_v)]
    return mat, starts, end


def route_nodes(prep, nodes, uavs, time_limit_s: float, initial=None,
                solution_limit: int = 2000, guided: bool = True) -> list:
    """Routes (lists of viewpoint ids) visiting every node once, one per entry of ``uavs``.

    ``initial`` (routes of viewpoint ids) seeds the search.  The search stops
    after ``solution_limit`` solutions, which keeps it deterministic;
    ``time_limit_s`` is only a safety net on slow machines.
    """
    nodes = np.asarray(nodes, dtype=np.int64)
    if len(nodes) == 0:
        return [[] for _ in uavs]
    mat, starts, end = transit_matrix(prep, nodes, list(uavs))
    manager = pywrapcp.RoutingIndexManager(len(mat), len(uavs), starts, [end] * len(uavs))
    model = pywrapcp.RoutingModel(manager)
    transit = model.RegisterTransitMatrix(mat.tolist())
    model.SetArcCostEvaluatorOfAllVehicles(transit)
    model.AddDimension(transit, 0, int(mat[mat < FORBIDDEN].sum()) + 1, True, "time")
    model.GetDimensionOrDie("time").SetGlobalSpanCostCoefficient(SPAN_WEIGHT)
    params = pywrapcp.DefaultRoutingSearchParameters()
    params.first_solution_strategy = routing_enums_pb2.FirstSolutionStrategy.PATH_CHEAPEST_ARC
    meta = routing_enums_pb2.LocalSearchMetaheuristic
    params.local_search_metaheuristic = meta.GUIDED_LOCAL_SEARCH if guided else meta.GREEDY_DESCENT
    params.time_limit.FromMilliseconds(max(int(time_limit_s * 1000), 50))
    params.solution_limit = solution_limit
    if initial is not None:
        index = {int(e): i for i, e in enumerate(nodes)}
        model.CloseModelWithParameters(params)
        start = model.ReadAssignmentFromRoutes([[index[e] for e in r] for r in initial], True)
        solution = model.SolveFromAssignmentWithParameters(start, params)
    else:
        solution = model.SolveWithParameters(params)
    if solution is None:
        raise RuntimeError("OR-Tools found no route for the selected viewpoints")
    return solved_routes(model, manager, solution, len(uavs), nodes)


def solved_routes(model, manager, solution, n_uavs: int, nodes) -> list:
    """Each UAV's route of an OR-Tools ``solution``, as the viewpoints ``nodes`` its
    matrix rows stand for (the start and end rows after them are left out)."""
    routes = []
    for v in range(n_uavs):
        idx, route = model.Start(v), []
        while not model.IsEnd(idx):
            node = manager.IndexToNode(idx)
            if node < len(nodes):
                route.append(int(nodes[node]))
            idx = solution.Value(model.NextVar(idx))
        routes.append(route)
    return routes


def default_time_limit(n_nodes: int) -> float:
    """Safety-net seconds for one OR-Tools call: grows with size, bounded."""
    return float(min(30.0, 5.0 + 0.05 * n_nodes))
