"""Chunked stages, in this process or as dask.distributed tasks.

The heavy stages whose work splits into independent chunks (checking the
travel graph's edges, rows of hidden travel times) hand their chunks to
`run_chunks`. Without a dask client the chunks run here in order (each one
uses every core through numba's threads) and report progress as they end;
with a client they run as tasks on its workers, the data every chunk shares
scattered to them once. Either way the results come back in chunk order, so
a plan is the same wherever it was computed.

Dask is the scheduler: nothing here decides where a task runs.
"""

import itertools
from concurrent.futures import CancelledError, ThreadPoolExecutor
from contextlib import contextmanager
from typing import Callable, Optional

from common.errors import ClusterError, InputError

#: above this many grid cells `gcs plan` starts a local dask cluster by itself. Below
#: it this process is faster and lighter, as measured on 2 cores: 2048² (4.2 M
#: cells) planned in 238 s and 6.9 GiB here against 260 s and 7.5 GiB (summed over
#: the processes) on a LocalCluster of 2 workers, the same plan
LOCAL_CLUSTER_CELLS = 8_000_000

def run_chunks(fn: Callable, chunks, shared: tuple = (), client=None,
               progress: Optional[Callable[[float], None]] = None, threads: int = 1,
               total: Optional[int] = None, scatter: bool = False) -> list:
    """[fn(*shared, chunk) for chunk in chunks], here or on ``client``'s workers.
    ``threads`` > 1: here, on that many threads (for work that releases the GIL
    but has no threads of its own, such as scipy's Dijkstra). ``chunks`` may be
    an iterator of ``total`` chunks, each made only when its turn comes (large
    ones); ``scatter``: each chunk goes straight to a worker when one is free for
    it, and this process keeps no reference to it."""
    total = len(chunks) if total is None else total
    if not total:
        return []
    if client is None:
        out = []
        for i, result in enumerate(_here(fn, shared, chunks, threads)):
            out.append(result)
            if progress is not None:
                progress((i + 1) / total)
        return out
    from distributed import as_completed

    # hash=False: a later stage scattering the same data must not share (and lose) its
    # key; direct: straight to the workers, not through the scheduler, which would
    # keep a copy (the 4096² travel graph: 4 GiB more in the scheduler's process)
    scattered = (client.scatter(list(shared), broadcast=True, hash=False, direct=True)
                 if shared else [])
    order = {}

    def submit(i, chunk):
        data = client.scatter(chunk, hash=False, direct=True) if scatter else chunk
        future = client.submit(_on_worker, fn, *scattered, data, pure=False)
        order[future.key] = i
        return future

    # a window of chunks in flight, the next one sent as one ends: the scheduler (which
    # holds a task's arguments) and the workers hold a few chunks, not all of them (GBs
    # on large areas); a large scattered chunk waits until a worker is free for it
    threads = sum(client.nthreads().values()) or 1
    pending = enumerate(chunks)
    running = as_completed([submit(i, c) for i, c in itertools.islice(
        pending, threads if scatter else 2 * threads)], with_results=True)

    def submit_next():  # the chunk is let go with this frame once sent
        for i, chunk in itertools.islice(pending, 1):
            running.add(submit(i, chunk))

    out = [None] * total
    for done, (future, result) in enumerate(running, 1):
        out[order.pop(future.key)] = result
        future.release()  # its result leaves the worker now, not when all are done
        submit_next()
        if progress is not None:
            progress(done / total)
    return out


def chunks_of(items, size) -> list:
    """``items`` in consecutive chunks of at most ``size``."""
    return [items[i:i + size] for i in range(0, len(items), size)]


def progress_part(progress, lo, hi):
    """A progress callback mapping [0, 1] onto [lo, hi] of ``progress``."""
    if progress is None:
        return None
    return lambda f: progress(lo + (hi - lo) * f)


def n_threads() -> int:
    """numba's threads in this process (imported when asked: this module stays light)."""
    from numba import get_num_threads
    return max(1, int(get_num_threads()))


def _here(fn, shared, chunks, threads):
    """The chunks' results in order, in this thread (whose numba threads then serve
    every chunk) or on a pool of ``threads``."""
    if threads <= 1:
        for chunk in chunks:
            result = fn(*shared, chunk)
            del chunk  # a large chunk (a part's problem) is let go before the next is made
            yield result
        return
    with ThreadPoolExecutor(threads) as pool:
        yield from pool.map(lambda chunk: fn(*shared, chunk), chunks)


def _on_worker(fn, *args):
    """A chunk on a dask worker: one numba thread per worker thread, as the cluster
    already runs one task per core."""
    import numba

    numba.set_num_threads(1)
    return fn(*args)


@contextmanager
def dask_client(scheduler, cells: int, log=None):
    """The dask client a plan's chunked stages use, closed afterwards if made here:
    ``scheduler`` a ``distributed.Client`` (used as it is), the address of a dask
    scheduler, "auto" (a LocalCluster with a worker per core for a grid over
    `LOCAL_CLUSTER_CELLS` cells, else none), or None (none: this process).
    ``log`` is told which cluster, when there is one. An address no scheduler
    answers at is an `InputError`; a cluster that loses a worker's work mid-plan
    raises `ClusterError`."""
    if scheduler is None or (scheduler == "auto" and cells <= LOCAL_CLUSTER_CELLS):
        yield None
        return
    from distributed.comm import CommClosedError
    from distributed.scheduler import KilledWorker

    mine = isinstance(scheduler, str)
    client = _start(None if scheduler == "auto" else scheduler, cells, log) if mine \
        else scheduler
    try:
        yield client
    except (KilledWorker, CancelledError, CommClosedError) as exc:
        # most often a worker killed for memory (by its nanny or the system), with the
        # chunks it held: the plan cannot be finished from here
        raise ClusterError(f"dask cluster: a worker died or lost its data while planning "
                           f"({type(exc).__name__}); the workers may be short of memory: "
                           "give them more, or plan in more parts (--parts)") from None
    finally:
        if mine:
            client.close()
            if client.cluster is not None:
                client.cluster.close()


def _start(address: Optional[str], cells: int, log=None):
    from distributed import Client, LocalCluster

    if address is not None:
        try:
            client = Client(address)
        except (OSError, ValueError, TypeError) as exc:
            reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            raise InputError("--scheduler", f"no dask scheduler answers at {address}: "
                                            f"{reason}") from None
        what = f"dask cluster at {address} ({len(client.scheduler_info()['workers'])} workers)"
    else:
        import os

        cluster = LocalCluster(n_workers=os.cpu_count() or 1, threads_per_worker=1,
                               processes=True, dashboard_address=None)
        client = Client(cluster)
        what = f"a local dask cluster of {len(cluster.workers)} worker processes"
    if log is not None:
        log(f"{cells:,} grid cells: the travel graph and travel times run on {what}")
    return client
