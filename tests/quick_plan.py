"""Plans for the tests that judge a plan's routes, not how near optimal it is."""

from planner.pipeline import allocate, launch_starts, prepare


def plan_routes(scenario, terrain=None, outposts=None):
    """`planner.pipeline.plan_mission` with only the quick lower bounds: the strong
    one was most of such a test's time (5-8 CPU s of 7-12 in test_fleet), and is
    judged where it is the point (test_coverage_alns, test_exact)."""
    ctx = prepare(scenario, terrain=terrain, outposts=outposts)
    return ctx, allocate(ctx, scenario.uavs, launch_starts(ctx), strong_bound=False,
                         scheduler="auto")
