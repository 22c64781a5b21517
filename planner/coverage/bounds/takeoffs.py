"""The takeoff-order bound: the vehicles of one base take off one at a time.

**The relaxation.** A base's column holds one airborne vehicle at a time
(`planner.fleet.columns`), and a vehicle is in it for at least its vertical takeoff
(straight up over the base, below the column's top). So on the fleet clock (t = 0 at
the first takeoff) the i-th vehicle to leave a base (i = 0, 1, ...) takes off no
sooner than i takeoffs after the first, and its first snapshot comes no sooner than
that delay plus its way out. The vehicles of a base are interchangeable in the
coverage problem (the same ways out), so whichever order a plan takes, the problem
with the i-th vehicle of each base's ways out lengthened by its delay is a relaxation
of the timed plan: every bound of that problem (`bounds.lower_bounds`) bounds the
coverage time a plan prints on the fleet clock, not only its routes' times.

**Cost.** The same problem with ``launch_out`` shifted (the target classes shared),
but the vehicles of a base no longer share their ways out, so the route bounds price
a launch group per vehicle instead of one per base, within the same budget (the demo,
4 UAVs from one base: `lower_bounds` 2.0 -> 2.9 s with the plan's 2 s, 8.0 -> 6.8 s
with 20 s). The delays come from the plan's starts (`planner.launch.takeoff_delays`);
a vehicle already in the air (a re-plan) has none.
"""

from dataclasses import replace

import numpy as np


def delayed(prep, delays):
    """``prep`` (a `model.prepared.Prepared`: the bounds' class problem) with UAV r's
    ways out lengthened by ``delays[r]`` seconds; ``prep`` itself without launch points
    or delays."""
    if delays is None or not prep.has_launch or not np.any(np.asarray(delays) > 0):
        return prep
    lo = prep.launch_out + np.asarray(delays, float)[:, None]
    return replace(prep, problem=replace(prep.problem, launch_out=lo), launch_out=lo)


__all__ = ["delayed"]
