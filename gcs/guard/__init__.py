"""The separation guard: keeps airborne vehicles apart when they drift from the plan.

A plan proves its vehicles separated on its own schedule, and its base columns
used by one vehicle at a time (`planner.fleet.columns`); real ones drift from it
(wind, speed, a late takeoff, a slow spool-up). Each flight-loop step the guard
predicts where every airborne vehicle will be over the next `horizon` seconds of
fleet time: from its reported position (carried forward to now at its reported
velocity) along the rest of its route, at the planned speeds, stops and holds,
down to its landing (`planner.fleet.Profile`: what it flies, not a straight line
that ignores its turns); a held vehicle stays where it is. A conflict is two
predictions closer than the separation (`Trajectory.first_conflict`, exact) or
two in one base column at once. The guard holds one of the pair where it is, in
its firmware's hold mode, on its proven leg, so hidden: the one of lower priority
(the plan's: the later placed on the fleet clock; before it, a vehicle short of
battery, which every second held costs), unless holding it would still be in the
other's way, then the other; both only when neither alone clears it. Two
already in one column: the one that leaves it first on its route (the upper one
climbing out, the lower one landing) goes, the other holds.

The guard reacts in its own time: its loop (measured, `loop_s`), a command's way
to the vehicle (measured, `command_s`) and a position report's way down (with the
command's way up, one acknowledged command's round trip: `latency_s`), which at a
speed-up of the vehicles' clock are that many times more seconds of flight. The
horizon counts them, and a vehicle about to be held is predicted flying on along
its route for that long before it stands (`reaction_s`): on a busy machine a loop
of 0.5 s is 50 s of flight at 100x.

A held vehicle flies on, highest priority first, no sooner than two of the
guard's loops after its hold, and only once its route from where it stands keeps
`RESUME_FACTOR` separations clear of every other's prediction and shares no
column with another within the horizon. From closer than that to another (two
in one base column), it flies on only where its route parts from the other
*standing* (the other's own motion is not counted on: at the top of a column a
copter lingers as it turns to its first leg), and in a column only if it leaves
the column first. A held vehicle in its base column with nothing left to
photograph, only the column's top before its landing (`lands_here`: a re-plan
that brought it home as it took off), is flown on by landing from where it
stands: up to the top it would climb through the one descending above it, each
waiting on the other for good.

A takeoff is judged as a resume from the pad (`in_way_of_takeoff`, asked by the
flight's departures): it waits while an airborne vehicle is in the way of its
climb or route, the guard seeing only vehicles in the air.

Held vehicles that each wait on another held one (two head-on on one leg, one
coming down a column the other climbs) would wait for good: a cycle of them
found on `MIN_HOLD_LOOPS` loops running is `deadlocked`, and the flight re-plans
them from where they stand (its fleet clock orders who goes first); nothing
else would free them but a battery running low.

A vehicle a re-plan holds until its own time to fly on (`waiting`) is the re-plan's:
the guard never holds or resumes it (resumed early, it flew its new route ahead of
time, and its resume at that time then sent it back to the route's first item in a
straight line, through a hill), and predicts it standing until then.

Every hold and resume is an event, and `report` gives them with the closest
approach seen between each pair (from telemetry).
"""

from .fleet import GuardFleet
from .predict import closest_ahead
from .separation import SeparationGuard, hold_spans

__all__ = ["GuardFleet", "SeparationGuard", "closest_ahead", "hold_spans"]
