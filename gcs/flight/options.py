"""What a flight is told (`FlyOptions`), what stops it (`FlightError`), and the
figures its parts share."""

from dataclasses import dataclass, field
from pathlib import Path

from gcs.monitor import SWAP_SILENCE_S

FORMAT = "gcs-flight/1"
FLIGHT_FILE = "flight.json"
PLOT_FILE = "flight.png"
TLOG_PATTERN = "vehicle_{sysid}.tlog"
#: the plan made from where the vehicles stand (``from_where_they_stand``), in the output
PLAN_FROM_HERE = "plan-from-where-they-stand"
#: wall seconds between two rounds of the flight loop (the guard's step among them)
LOOP_S = 0.1
#: how far (m) a vehicle may stand from its launch point when the plan names no track
#: tolerance (plans older than it)
LAUNCH_TOLERANCE_M = 5.0


@dataclass
class FlyOptions:
    output: Path | str = "flight"
    lost_after_s: float = 5.0  # wall seconds without HEARTBEAT before a vehicle is lost
    signing_key: bytes | None = None
    assign: dict = field(default_factory=dict)  # sysid -> plan vehicle id (default: in order)
    connect_timeout_s: float = 30.0
    ready_timeout_s: float = 60.0
    protocol_timeout_s: float = 1.5  # mission protocol: wait per message before a retry
    protocol_retries: int = 5  # mission protocol and commands: resends before giving up
    max_items: int | None = None  # items per upload at most (segments below the capacity)
    timeout_s: float | None = None  # after this many wall seconds: ask, or bring them home
    tlog: bool = True
    forward: object = None  # gcs.forward.Forwarder: the fleet's MAVLink relayed (--forward)
    live: bool = True  # rich status table on a terminal, event lines otherwise
    plot: bool = True
    auto_turnaround: bool = False  # between sorties: a fresh battery reported is enough
                                   # (simulators, SITL); else the operator confirms too
    from_where_they_stand: bool = False  # a vehicle off its launch point: plan again with
                                         # its base where it stands (else it is refused)
    set_failsafes: bool = False  # write the failsafes' hidden-safe values (else a vehicle
                                 # whose failsafe would leave the proof is refused)
    swap_silence_s: float = SWAP_SILENCE_S  # wall s one down for its battery swap may be
                                            # silent (powered down) before it is lost

    @property
    def protocol(self) -> dict:
        """Keyword arguments of the mission protocol calls (timeouts and retries)."""
        return {"timeout_s": self.protocol_timeout_s, "retries": self.protocol_retries}


class FlightError(Exception):
    """The flight could not go on (a vehicle refused its start, re-tasking failed)."""


def launch_tolerance(plan) -> float:
    """How far (m) a vehicle may stand from where its route starts: the plan's track
    tolerance, the room its takeoff column is proven with (at least
    `MIN_LAUNCH_TOLERANCE_M`: GNSS on the ground)."""
    from gcs.monitor import MIN_LAUNCH_TOLERANCE_M

    return max(float(plan.params.get("track_tolerance_m", LAUNCH_TOLERANCE_M)),
               MIN_LAUNCH_TOLERANCE_M)
