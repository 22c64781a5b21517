"""Flying a plan: connect, upload, start, monitor, re-task on losses, report.

    report = fly(plan_dir, ["tcp:127.0.0.1:5760", ...], FlyOptions(output="flight"))

A `Flight` coordinates parts that each own one concern, in a module each:
``preflight`` (where the vehicles stand, their failsafes and rates, before
arming), ``departures`` (takeoffs and resumes on the fleet clock, one vehicle
in a base column at a time), ``batteries`` (the battery watch, the swaps
between sorties), ``holds`` (what the separation guard's hold and resume mean
per firmware), ``report`` (flight.json and its verdict); ``state`` is what they
share. The loop itself, the uploads and the re-tasking are the flight's
(``flight``).
"""

from gcs.monitor import LANDED, LOST

from .flight import Flight, assign_vehicles, fly
from .options import FLIGHT_FILE, LOOP_S, PLAN_FROM_HERE, PLOT_FILE, FlightError, FlyOptions
from .preflight import FailsafeRefused

__all__ = ["FLIGHT_FILE", "FailsafeRefused", "Flight", "FlightError", "FlyOptions", "LANDED",
           "LOOP_S", "LOST", "PLAN_FROM_HERE", "PLOT_FILE", "assign_vehicles", "fly"]
