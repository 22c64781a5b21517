"""One profile per autopilot firmware: everything that differs between ArduPilot and PX4.

    from autopilots import profile, profile_of_heartbeat, NAMES
    ap = profile("ardupilot")
    ap.home_item, ap.hold_mode, ap.mode_number("GUIDED"), ap.start_sequence, ap.rates

A new firmware, or a new quirk of one, is one module here (`ardupilot`,
`px4`), built on `autopilots.base.Autopilot`. `planner`, `missions` and `gcs`
import this package; the simulator (`gcs.sim.flavours`) builds its vehicle-side
mirror from the same profiles. The MAVLink numbers they all use are
`autopilots.mavlink`'s. It imports nothing else of the project.
"""

from . import ardupilot, px4
from .base import ACCEPT_RADIUS_M, Autopilot, Rates, Step

#: every profile, by name; the one list of firmware names
PROFILES = {p.name: p for p in (ardupilot.PROFILE, px4.PROFILE)}
NAMES = tuple(PROFILES)
ARDUPILOT, PX4 = ardupilot.PROFILE.name, px4.PROFILE.name
#: the firmware planned for where none is named: a scenario's default, and what a
#: plan.json that names none (an older version's) was made for
DEFAULT = ARDUPILOT
#: whose modes a generic autopilot (neither) is asked in: ArduPilot's plain
#: custom-mode numbers
GENERIC_MODES = ARDUPILOT


def profile(name: str) -> Autopilot:
    """The profile of firmware ``name`` ("ardupilot", "px4"); KeyError naming the choices."""
    try:
        return PROFILES[str(name).lower()]
    except KeyError:
        raise KeyError(f"unknown autopilot {name!r}; known: {', '.join(NAMES)}") from None


def firmware_of(params=None, given=None) -> str:
    """The firmware a plan is for: ``given`` (a command's option) first, then the
    one its ``params`` name (plan.json's, a scenario's), else `DEFAULT`."""
    return given or (params or {}).get("firmware") or DEFAULT


def profile_of_heartbeat(autopilot_type: int) -> Autopilot | None:
    """The profile behind a HEARTBEAT's ``autopilot`` field (MAV_AUTOPILOT); None for
    an autopilot that is neither."""
    for p in PROFILES.values():
        if p.mav_autopilot == int(autopilot_type):
            return p
    return None


__all__ = [
    "ACCEPT_RADIUS_M",
    "ARDUPILOT",
    "DEFAULT",
    "GENERIC_MODES",
    "NAMES",
    "PROFILES",
    "PX4",
    "Autopilot",
    "Rates",
    "Step",
    "firmware_of",
    "profile",
    "profile_of_heartbeat",
]
