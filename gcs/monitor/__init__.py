"""Following each vehicle from its telemetry: progress, snapshots, losses, landing.

A `Monitor` subscribes to every `gcs.link.VehicleLink` of the flight. From the
reader threads it records the track (GLOBAL_POSITION_INT), the mission items
reached (MISSION_ITEM_REACHED, mapped to plan waypoints through
`VehicleMission.waypoint_of_item`; an item reached means every waypoint before it
was, as PX4 reports a waypoint followed by DO commands with the number of the last
of them, and only the latest of several reached between two reports) and camera
feedback. A snapshot counts as
taken when its waypoint is reached: ArduPilot reports MISSION_ITEM_REACHED for
navigation items only, and camera feedback only with a camera configured, so
the waypoint is the one signal every autopilot gives. Camera feedback, where
it comes, is kept beside it.

Loss detection (`check_losses`, on the wall clock, by the flight loop and by a
thread of its own while the flight computes or waits: `watch_losses`):
a vehicle is lost when nothing (no HEARTBEAT, no report) has come for
``lost_after_s`` seconds,
or when it disarms in the air. A link that comes back earlier is not a loss.
A silence that starts where the plan predicts a radio shadow (`gcs.contact`) is
an event, out of contact as planned; the vehicle is lost only when it is not heard
by the shadow's end at its measured pace, with a margin (overdue).

A vehicle in the air further from its route's proven legs than the plan's track
tolerance (`gcs.corridor`) flies where nothing was proven: an event when it
leaves them and when it is back, and an episode in ``off_route``.

Touching the ground is a landing only at a base of its flight (the launch point,
or the base a sortie lands at) after the mission's last waypoint (the one above
that base, before the landing). Anywhere else, or earlier, it is a crash: the
vehicle is lost with its snapshots. So is a vehicle whose altitude goes below
the terrain (the plan's DEM) + ``CRASH_MARGIN_M`` away from its bases, whether
or not it disarms.

The package, a module a job:

- ``records``: the flight states, the thresholds, `VehicleProgress` and its
  `Snapshot` list (plain data);
- ``telemetry``: the reader threads' handlers, one a message kind (`_HANDLERS`);
- ``route``: the missions given, the waypoints passed (snapshots), the
  proven legs kept or left;
- ``landing``: on the ground, landed at a base or crashed (`on_pad`);
- ``losses``: silences past ``lost_after_s`` (`StallClock`), lost vehicles, and
  the ones heard back and taken again (`_rejoin`, `catch_up`);
- ``shadows``: out of contact as planned, overdue, and where its plan has a
  silent vehicle (`planned_at`);
- ``monitor``: the `Monitor` itself: following the links, the event log, the
  flight state the flight sets, the views of the status table.

The parts are mixins of the one `Monitor`, not functions taking it: every
judgment reads and writes the same vehicle records under the same lock, and
calls on the others (a HEARTBEAT ends a radio shadow, a position report lands a
vehicle or loses it). As methods they stay one object with one lock, called by
the names the flight, the guard and the tests call them by (`monitor.on_pad`,
`monitor._on`). A part calls the others' methods on ``self``; the state itself
(``vehicles``, ``links``, ``_lock``, `Monitor.event`) is the `Monitor`'s, set up
in its ``__init__``.
"""

from common.geo import distance_m  # imported from here by gcs.retask

from .losses import StallClock
from .monitor import Monitor, mission_items, shown_item
from .records import (
    CRASH_MARGIN_M,
    DISARM_REPORTS,
    FLYING,
    HOLDING,
    LANDED,
    LANDED_AGL_M,
    LAUNCH_RADIUS_M,
    LIFTOFF_M,
    LOST,
    MIN_LAUNCH_TOLERANCE_M,
    RETURNING,
    SETTLE_S,
    SETTLED_MPS,
    STARTING,
    STRANDED,
    SWAP_SILENCE_S,
    TRACK_PERIOD_S,
    WAITING,
    Snapshot,
    VehicleProgress,
)

__all__ = ["CRASH_MARGIN_M", "DISARM_REPORTS", "FLYING", "HOLDING", "LANDED", "LANDED_AGL_M",
           "LAUNCH_RADIUS_M", "LIFTOFF_M", "LOST", "MIN_LAUNCH_TOLERANCE_M", "RETURNING",
           "SETTLED_MPS", "SETTLE_S", "STARTING", "STRANDED", "SWAP_SILENCE_S", "TRACK_PERIOD_S",
           "WAITING", "Monitor", "Snapshot", "StallClock", "VehicleProgress", "distance_m",
           "mission_items", "shown_item"]
