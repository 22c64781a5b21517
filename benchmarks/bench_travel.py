"""The hidden travel graph: proofs hinted by a neighbour's horizon against proofs
that walk every whole ray (the reference), on bench_scale's synthetic UTM DEMs
(30 m cells, 5 outposts of unlimited range), measured in the same run.

    .venv/bin/python -m benchmarks travel [--quick]

Prints wall and CPU seconds of each, their ratio, and the edges the hinted
graph lacks (must be none: a hint never loses a proof) or adds (proofs a hint
found that the whole ray did not). --quick: 512² only (the reference on 1024²
takes minutes).
"""

import argparse
import tempfile
import time
import warnings
from pathlib import Path

SIZES = (512, 1024)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="512² only")
    args, _ = ap.parse_known_args(argv)
    print(f"{'grid':<8}{'nodes':>10}{'edges':>12}{'hinted s':>16}{'reference s':>18}"
          f"{'ratio':>8}  lost / added edges")
    for n in SIZES[:1] if args.quick else SIZES:
        _row(n)


def _row(n):
    from planner.travel import TravelGraph

    surface = _surface(n)
    TravelGraph(_surface(64))                       # compile outside the timings
    timed = {}
    for hints in (True, False):
        t, cpu = time.perf_counter(), time.process_time()
        graph = TravelGraph(surface, hints=hints)
        timed[hints] = (graph, time.perf_counter() - t, time.process_time() - cpu)
    (fast, wall, cpu), (ref, ref_wall, ref_cpu) = timed[True], timed[False]
    lost, added = _edge_difference(ref, fast)
    print(f"{n}²{'':<4}{fast.n_nodes:>10,}{fast.n_edges:>12,}{wall:>9.1f} /{cpu:>5.1f}"
          f"{ref_wall:>11.1f} /{ref_cpu:>5.1f}{wall / ref_wall:>8.2f}  {lost} / {added}", flush=True)


def _edge_difference(reference, graph) -> tuple:
    """(edges of ``reference`` missing from ``graph``, edges only ``graph`` has)."""
    def pairs(g):
        e = g.edges()
        return set(zip(e["src"].tolist(), e["dst"].tolist()))

    a, b = pairs(reference), pairs(graph)
    return len(a - b), len(b - a)


def _surface(n):
    """bench_scale's DEM and outposts for an n x n grid, and their exposure surface."""
    from benchmarks.bench_scale import _inputs
    from planner.exposure import compute_exposure, load_outposts
    from planner.terrain import load_dem

    warnings.simplefilter("ignore")
    dem, posts, _ = _inputs(n, Path(tempfile.mkdtemp(prefix="bench-travel-")))
    terrain = load_dem([str(dem)])
    return compute_exposure(terrain, load_outposts(posts, terrain))


if __name__ == "__main__":
    main()
