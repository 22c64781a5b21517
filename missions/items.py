"""`MissionItem`: one MAVLink mission item, as the files and the wire hold it.

Coordinates are kept as the user reads them: for global frames ``x`` is the
latitude and ``y`` the longitude in degrees, ``z`` the altitude in metres. On
the wire (MISSION_ITEM_INT) global latitudes and longitudes are integers in
degE7, local ones integers in metres * 1e4, and for every other frame
(MAV_FRAME_MISSION for commands without a position) x and y are the plain
integer values of param5 and param6.
"""

import math
from dataclasses import dataclass

from autopilots.mavlink import (
    COMMAND_NAMES,
    GLOBAL_FRAMES,
    LOCAL_FRAMES,
    NAV_POSITION_COMMANDS,
    SAME_FRAME,
)

# isort: split
# The other MAVLink numbers the ground station and the tests take from here are
# `autopilots.mavlink`'s, handed on (a block of their own: none is used here).
from autopilots.mavlink import (  # noqa: F401 - handed on
    DO_CHANGE_SPEED,
    DO_DIGICAM_CONTROL,
    DO_LAND_START,
    FRAME_GLOBAL,
    FRAME_MISSION,
    IMAGE_START_CAPTURE,
    NAV_LAND,
    NAV_LAST,
    NAV_RETURN_TO_LAUNCH,
    NAV_TAKEOFF,
    NAV_WAYPOINT,
)

DEG_E7 = 1e7
LOCAL_SCALE = 1e4


@dataclass
class MissionItem:
    seq: int
    frame: int
    command: int
    current: int
    autocontinue: int
    param1: float
    param2: float
    param3: float
    param4: float
    x: float  # latitude, degrees (global frames); param5 otherwise
    y: float  # longitude, degrees (global frames); param6 otherwise
    z: float  # altitude, metres (AMSL in MAV_FRAME_GLOBAL); param7 otherwise
    mission_type: int = 0

    @property
    def is_global(self) -> bool:
        return int(self.frame) in GLOBAL_FRAMES

    @property
    def is_position(self) -> bool:
        """A place the vehicle flies to (navigation command in a global frame)."""
        return self.is_global and int(self.command) in NAV_POSITION_COMMANDS

    @property
    def name(self) -> str:
        return COMMAND_NAMES.get(int(self.command), f"MAV_CMD({int(self.command)})")

    def to_int(self) -> dict:
        """The fields of a MISSION_ITEM_INT message (without target ids)."""
        return {
            "seq": int(self.seq), "frame": int(self.frame), "command": int(self.command),
            "current": int(self.current), "autocontinue": int(self.autocontinue),
            "param1": float(self.param1), "param2": float(self.param2),
            "param3": float(self.param3), "param4": float(self.param4),
            "x": _to_wire(self.x, self.frame), "y": _to_wire(self.y, self.frame),
            "z": float(self.z), "mission_type": int(self.mission_type),
        }

    @classmethod
    def from_int(cls, msg) -> "MissionItem":
        """From a pymavlink MISSION_ITEM_INT or MISSION_ITEM message (or any object
        with those fields: a MISSION_ITEM_INT's when it has no ``get_type``)."""
        kind = msg.get_type() if hasattr(msg, "get_type") else "MISSION_ITEM_INT"
        frame = int(msg.frame)
        if kind == "MISSION_ITEM_INT":
            x, y = _from_wire(msg.x, frame), _from_wire(msg.y, frame)
        else:
            x, y = float(msg.x), float(msg.y)
        return cls(seq=int(msg.seq), frame=frame, command=int(msg.command),
                   current=int(msg.current), autocontinue=int(msg.autocontinue),
                   param1=float(msg.param1), param2=float(msg.param2),
                   param3=float(msg.param3), param4=float(msg.param4),
                   x=x, y=y, z=float(msg.z),
                   mission_type=int(getattr(msg, "mission_type", 0)))

    def differences(self, other, tol: float = 1e-5) -> list:
        """Fields that differ beyond what the wire keeps, e.g. ``["z 500.0 != 501.0"]``.

        ``current`` is not compared (autopilots set it as they please). Params and
        ``z`` are float32 on the wire: equal within ``tol`` relative (and 1 cm for
        ``z``); NaN equals NaN. Global x / y are equal within 1.5e-7 degrees (degE7
        rounding), other x / y after rounding to the wire's integers.
        """
        out = []
        if SAME_FRAME.get(int(self.frame), int(self.frame)) != \
                SAME_FRAME.get(int(other.frame), int(other.frame)):
            out.append(f"frame {self.frame} != {other.frame}")
        for name in ("seq", "command", "autocontinue", "mission_type"):
            if int(getattr(self, name)) != int(getattr(other, name)):
                out.append(f"{name} {getattr(self, name)} != {getattr(other, name)}")
        for name in ("param1", "param2", "param3", "param4"):
            if not _close(getattr(self, name), getattr(other, name), tol, 1e-6):
                out.append(f"{name} {getattr(self, name)!r} != {getattr(other, name)!r}")
        if not _close(self.z, other.z, tol if not self.is_global else 0.0, 0.01):
            out.append(f"z {self.z!r} != {other.z!r}")
        for name in ("x", "y"):
            a, b = getattr(self, name), getattr(other, name)
            same = (_close(a, b, 0.0, 1.5e-7) if self.is_global
                    else _to_wire(a, self.frame) == _to_wire(b, other.frame))
            if not same:
                out.append(f"{name} {a!r} != {b!r}")
        return out

    def same_as(self, other, tol: float = 1e-5) -> bool:
        """Equal as far as the wire and the files can tell (see `differences`)."""
        return not self.differences(other, tol)


def first_difference(a: list, b: list, tol: float = 1e-5):
    """None when two item lists are the same, else a one-line description."""
    if len(a) != len(b):
        return f"{len(a)} items != {len(b)} items"
    for one, two in zip(a, b):
        diff = one.differences(two, tol)
        if diff:
            return f"item {one.seq} ({one.name}): " + ", ".join(diff)
    return None


def renumber(items: list) -> list:
    """Items with seq 0..n-1 in order and only the first one marked current."""
    for seq, item in enumerate(items):
        item.seq = seq
        item.current = 1 if seq == 0 else 0
    return items


def _to_wire(value: float, frame: int) -> int:
    value = float(value)
    if not math.isfinite(value):
        return 0
    if int(frame) in GLOBAL_FRAMES:
        return int(round(value * DEG_E7))
    if int(frame) in LOCAL_FRAMES:
        return int(round(value * LOCAL_SCALE))
    return int(round(value))


def _from_wire(value: int, frame: int) -> float:
    if int(frame) in GLOBAL_FRAMES:
        return int(value) / DEG_E7
    if int(frame) in LOCAL_FRAMES:
        return int(value) / LOCAL_SCALE
    return float(value)


def _close(a, b, rel: float, abs_: float) -> bool:
    a, b = float(a), float(b)
    if math.isnan(a) or math.isnan(b):
        return math.isnan(a) and math.isnan(b)
    return abs(a - b) <= max(abs_, rel * max(abs(a), abs(b)))
