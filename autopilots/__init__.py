"""One profile per autopilot firmware: everything that differs between ArduPilot and PX4.

    from autopilots import profile, profile_of_heartbeat, NAMES
    ap = profile("ardupilot")
    ap.home_item, ap.hold_mode, ap.mode_number("GUIDED"), ap.start_sequence

A new firmware, or a new quirk of one, is one module here (`ardupilot`,
`px4`), built on `autopilots.base.Autopilot`. `missions` and `gcs` import this
package; the simulator (`gcs.sim.flavours`) builds its vehicle-side mirror from
the same profiles. It imports nothing else of the project.
"""

from . import ardupilot, px4
from .base import Autopilot, Step

#: every profile, by name; the one list of firmware names
PROFILES = {p.name: p for p in (ardupilot.PROFILE, px4.PROFILE)}
NAMES = tuple(PROFILES)
ARDUPILOT, PX4 = ardupilot.PROFILE.name, px4.PROFILE.name


def profile(name: str) -> Autopilot:
    """The profile of firmware ``name`` ("ardupilot", "px4"); KeyError naming the choices."""
    try:
        return PROFILES[str(name).lower()]
    except KeyError:
        raise KeyError(f"unknown autopilot {name!r}; known: {', '.join(NAMES)}") from None


def profile_of_heartbeat(autopilot_type: int) -> Autopilot | None:
    """The profile behind a HEARTBEAT's ``autopilot`` field (MAV_AUTOPILOT); None for
    an autopilot that is neither."""
    for p in PROFILES.values():
        if p.mav_autopilot == int(autopilot_type):
            return p
    return None


__all__ = ["ARDUPILOT", "Autopilot", "NAMES", "PROFILES", "PX4", "Step", "profile",
           "profile_of_heartbeat"]
