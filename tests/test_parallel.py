"""The heavy stages on a dask cluster (two worker processes) give the same plan as
in this process; and a plan's heaviest stage keeps more than one core busy."""

import operator
import os
import warnings
from dataclasses import replace

import dask
import numba
import numpy as np
import psutil
import pytest

from common.errors import ClusterError
from planner.exposure import Outpost, compute_exposure
from planner.parallel import dask_client, run_chunks
from planner.pipeline import allocate, launch_starts, prepare
from planner.scenario import Scenario
from planner.terrain import synthetic_terrain
from planner.travel import build_travel_graph


def _problem(n, seed):
    terrain = synthetic_terrain(n, n, cell=30.0, seed=seed, family="mixed")
    outposts = []
    for k, (r, c) in enumerate([(n // 3, n // 3), (2 * n // 3, n // 2)]):
        x, y = terrain.xy(r, c)
        lon, lat = terrain.to_lonlat(x, y)
        outposts.append(Outpost(float(x), float(y), 10.0, float("inf"), float(lon),
                                float(lat), f"P{k}"))
    scenario = Scenario(sample=True, uavs=3, sensor_range_m=900.0, method="rt+ls").validate()
    return scenario, terrain, outposts


def test_local_cluster_gives_the_same_context_and_plan():
    """The chunked stages, and an area planned in parts (the parts solved as tasks)."""
    distributed = pytest.importorskip("distributed")
    scenario, terrain, outposts = _problem(120, 5)
    here = prepare(scenario, terrain=terrain, outposts=outposts, scheduler=None)
    in_parts = replace(scenario, parts=2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        # a task whose worker dies fails at once, not after retries on 3 more workers
        with dask.config.set({"distributed.scheduler.allowed-failures": 0}), \
                distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                         dashboard_address=None) as cluster, \
                distributed.Client(cluster) as client:
            there = prepare(scenario, terrain=terrain, outposts=outposts, scheduler=client)
            assert len(client.scheduler_info()["workers"]) == 2
            parts_there = allocate(replace(there, scenario=in_parts), 3, scheduler=client)
            # more chunks than run_chunks keeps in flight, from a list and from an
            # iterator, sent along or scattered: every result, in chunk order
            for scatter in (False, True):
                assert run_chunks(operator.mul, list(range(25)), (3,), client,
                                  scatter=scatter) == [3 * i for i in range(25)]
                assert run_chunks(operator.mul, iter(range(25)), (3,), client, total=25,
                                  scatter=scatter) == [3 * i for i in range(25)]
            # last (it costs a worker): a worker that dies mid-plan is one clear error
            with pytest.raises(ClusterError, match="a worker died"), dask_client(client, 0):
                run_chunks(lambda chunk: os._exit(1), [0], client=client)
    parts_here = allocate(replace(here, scenario=in_parts), 3)
    assert parts_here.plan.metrics["parts"] == 2
    assert [v.waypoints for v in parts_here.plan.vehicles] == \
        [v.waypoints for v in parts_there.plan.vehicles]
    for name in ("src", "dst", "dip"):
        np.testing.assert_array_equal(here.graph.edges()[name], there.graph.edges()[name])
    np.testing.assert_array_equal(here.travel, there.travel)
    a = allocate(here, 3, launch_starts(here))
    b = allocate(there, 3, launch_starts(there))
    assert [v.waypoints for v in a.plan.vehicles] == [v.waypoints for v in b.plan.vehicles]


def _thread_cpu() -> dict:
    """CPU seconds per thread of this process, by thread id."""
    return {t.id: t.user_time + t.system_time for t in psutil.Process().threads()}


def test_the_heaviest_stage_uses_more_than_one_core():
    """On 512 x 512 cells the travel graph (the heaviest terrain-bound stage) runs
    its checks on numba's threads: at least two threads each do a good share of
    its CPU work. Counted per thread, so that other work on the machine (which
    takes cores away, not work) cannot make it pass or fail."""
    scenario, terrain, outposts = _problem(512, 9)
    surface = compute_exposure(terrain, outposts, scenario.exposure_params())
    warm = synthetic_terrain(64, 64, cell=30.0, seed=1)
    build_travel_graph(compute_exposure(warm, []), scenario.travel_params())  # compiled first
    before = _thread_cpu()
    build_travel_graph(surface, scenario.travel_params())
    used = {t: cpu - before.get(t, 0.0) for t, cpu in _thread_cpu().items()}
    total = sum(used.values())
    busy = [t for t, cpu in used.items() if cpu > 0.25 * total]
    assert total > 1.0 and len(busy) >= min(2, numba.config.NUMBA_NUM_THREADS), used
