"""The takeoff-order bound (`bounds.takeoffs`): the vehicles of a base wait for its
column one after another, at least a takeoff each, and the bound of the timed plan
stays below its coverage time."""

import numpy as np

from planner.launch import Start, launch_starts, takeoff_delays


def _start(x, climb, held=None):
    return Start(np.array([x, 0.0, 150.0]), np.array([x, 0.0, 100.0]), climb, held=held)


def test_the_ith_vehicle_of_a_base_waits_i_takeoffs():
    """Per base in turn; a vehicle in the air (a re-plan) waits for nothing; no columns
    without a separation."""
    starts = [_start(0.0, 40.0), _start(500.0, 30.0), _start(0.0, 40.0), _start(0.0, 40.0),
              _start(500.0, 30.0), _start(0.0, 40.0, held=np.zeros(3))]
    assert np.allclose(takeoff_delays(starts, 30.0), [0, 0, 40, 80, 30, 0])
    assert takeoff_delays(starts, 0.0) is None and takeoff_delays(None, 30.0) is None


def test_the_planned_takeoffs_wait_at_least_that(planned):
    """The shared plan (3 UAVs from one launch point): its takeoffs, in order, are no
    earlier than the delays the bound assumes, and its bound is below its coverage."""
    starts = launch_starts(planned.ctx)
    delays = np.sort(takeoff_delays(starts, planned.ctx.scenario.separation_m))
    takeoffs = np.sort([v.takeoff_s for v in planned.plan.vehicles])
    assert len(takeoffs) == len(delays) == 3 and delays[1] > 0
    assert np.all(takeoffs >= delays - 1e-6), (takeoffs, delays)
    m = planned.plan.metrics
    assert 0 < m["lower_bound_s"] <= m["coverage_time_s"]
