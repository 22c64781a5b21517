"""``QGC WPL 110`` waypoint files (Mission Planner, MAVProxy): writer and reader.

One header line ``QGC WPL 110``, then one tab-separated line per item:
``seq current frame command param1 param2 param3 param4 x y z autocontinue``,
x / y in degrees for global frames.

Line 0 is always home, as QGroundControl and Mission Planner write and read
these files (a ``NAV_WAYPOINT`` at the launch point, ground altitude AMSL).
What happens to it on upload is the firmware's (`autopilots` profile,
``home_item``): ArduPilot keeps home as mission item 0, so the file holds
exactly the items uploaded; PX4 has no home item, so line 0 is written from the
launch point for the other programs and dropped on reading (the mission is
lines 1.., renumbered from 0). Files written before this layout, whose line 0
is the PX4 takeoff (``NAV_TAKEOFF``), are read too: a file whose line 0 is not
a ``NAV_WAYPOINT`` has no home line.

The format has no header field for the firmware a mission was built for, and
QGroundControl's loader takes every line after the header for an item of 12
columns (a ``#`` comment makes it refuse the whole file). So the mark is on the
home line, which nobody flies (ArduPilot overwrites item 0 with its own home,
PX4 is not given it, QGroundControl takes only its position for planned home):
params 1 to 4 are ``0, 0, MAV_AUTOPILOT, 0`` (3 ArduPilot, 12 PX4, the numbers
of a ``.plan``'s ``firmwareType``). Every file written for a firmware carries it
(`file_items`); the mission read for a firmware has it cleared again
(`mission_items`), so what is uploaded is what was built; `marked_firmware`
reads it. A file without it (another program's, or one of ours from before) has
none: what it is for is then left to its items (`missions.sources`).
"""

import math
from dataclasses import replace

from autopilots import NAMES, profile
from autopilots.mavlink import FRAME_GLOBAL, NAV_WAYPOINT
from common.errors import InputError
from common.fileio import write_text_atomic

from .items import MissionItem, renumber

HEADER = "QGC WPL 110"
#: MAV_AUTOPILOT number -> firmware name, for the mark on the home line
_MARKS = {float(profile(name).mav_autopilot): name for name in NAMES}


def file_items(items, firmware: str | None = None, home=None) -> list:
    """The lines of a file for mission ``items`` of ``firmware``: as they are where
    the firmware has a home item, else a home line 0 first (``home`` (lat, lon,
    alt AMSL), default the first position item's); line 0 marked as ``firmware``'s
    either way. ``firmware`` None: the lines as given, unmarked."""
    items = list(items)
    if firmware is None:
        return items
    autopilot = profile(firmware)
    if autopilot.home_item:
        line0, rest = split_home(items)
        if line0 is None:               # not a mission of this firmware: nothing to mark
            return items
        return [_marked(line0, firmware)] + [_copy(it) for it in rest]
    if home is None:
        first = next((it for it in items if it.is_position), None)
        home = (first.x, first.y, first.z) if first is not None else (0.0, 0.0, 0.0)
    line0 = MissionItem(0, FRAME_GLOBAL, NAV_WAYPOINT, 1, 1, 0.0, 0.0, 0.0, 0.0,
                        float(home[0]), float(home[1]), float(home[2]))
    return renumber([_marked(line0, firmware)] + [_copy(it) for it in items])


def _marked(line0, firmware: str) -> MissionItem:
    """The home line marked as written for ``firmware`` (params 0, 0, MAV_AUTOPILOT, 0)."""
    return replace(line0, param1=0.0, param2=0.0,
                   param3=float(profile(firmware).mav_autopilot), param4=0.0)


def marked_firmware(items) -> str | None:
    """The firmware a file's lines are marked as written for (`file_items`); None
    when its home line bears no mark (or it has no home line)."""
    line0, _ = split_home(items)
    if line0 is None or (line0.param1, line0.param2, line0.param4) != (0.0, 0.0, 0.0):
        return None
    return _MARKS.get(line0.param3)


def split_home(items) -> tuple:
    """(home item or None, the other items) of a file's lines: line 0 is home when
    it is a NAV_WAYPOINT (QGroundControl's layout), not when it is anything else
    (a PX4 file of the old layout starts with its takeoff)."""
    items = list(items)
    if items and items[0].seq == 0 and int(items[0].command) == NAV_WAYPOINT:
        return items[0], items[1:]
    return None, items


def mission_items(items, firmware: str, source="waypoints") -> list:
    """What ``firmware`` is given from a file's lines: home as item 0 where the
    firmware keeps one (InputError if the file has no home line), else without it."""
    home, rest = split_home(items)
    autopilot = profile(firmware)
    if autopilot.home_item:
        if home is None:
            raise InputError(source, f"line 2 is not a home position (a NAV_WAYPOINT): "
                                     f"{autopilot.title} missions start with home")
        if marked_firmware(items) is not None:      # the file's mark, not the mission's
            home = replace(home, param3=0.0)
        return renumber([_copy(home)] + [_copy(it) for it in rest])
    return renumber([_copy(it) for it in rest])


def _copy(it) -> MissionItem:
    return replace(it)


def waypoints_text(items, firmware: str | None = None, home=None) -> str:
    lines = [HEADER]
    for it in file_items(items, firmware, home):
        values = [f"{int(it.seq)}", f"{int(it.current)}", f"{int(it.frame)}", f"{int(it.command)}",
                  *(_number(v) for v in (it.param1, it.param2, it.param3, it.param4)),
                  _number(it.x, 9 if it.is_global else None),
                  _number(it.y, 9 if it.is_global else None),
                  _number(it.z), f"{int(it.autocontinue)}"]
        lines.append("\t".join(values))
    return "\n".join(lines) + "\n"


def write_waypoints(path, items, firmware: str | None = None, home=None) -> None:
    """Write ``items`` (a mission for ``firmware``; None: the lines as given)."""
    write_text_atomic(path, waypoints_text(items, firmware, home))


def read_waypoints(path, firmware: str | None = None) -> list:
    """The items of a ``QGC WPL 110`` file: its lines in file order, or with
    ``firmware`` the mission that firmware is given (`mission_items`)."""
    try:
        with open(path, encoding="utf-8") as f:
            text = f.read()
    except FileNotFoundError:
        raise InputError(path, "no such file") from None
    except UnicodeDecodeError:
        raise InputError(path, "not a QGC WPL 110 file (not text)") from None
    items = parse_waypoints(text, path)
    return items if firmware is None else mission_items(items, firmware, path)


def parse_waypoints(text: str, source="waypoints") -> list:
    lines = text.splitlines()
    if not lines or lines[0].strip() != HEADER:
        found = lines[0].strip()[:40] if lines else ""
        raise InputError(source, f"not a {HEADER} file (first line is {found!r})")
    items = []
    for number, line in enumerate(lines[1:], start=2):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        fields = line.split()
        if len(fields) != 12:
            raise InputError(source, f"line {number}: {len(fields)} values, expected 12")
        try:
            items.append(MissionItem(
                seq=int(fields[0]), current=int(fields[1]), frame=int(fields[2]),
                command=int(fields[3]), param1=float(fields[4]), param2=float(fields[5]),
                param3=float(fields[6]), param4=float(fields[7]), x=float(fields[8]),
                y=float(fields[9]), z=float(fields[10]), autocontinue=int(float(fields[11]))))
        except ValueError as exc:
            raise InputError(source, f"line {number}: {exc}") from None
    return items


def _number(value, decimals=None) -> str:
    value = float(value)
    if not math.isfinite(value):
        return "NaN" if math.isnan(value) else repr(value)
    if decimals is not None:
        return f"{value:.{decimals}f}"
    return repr(value) if value != int(value) or abs(value) >= 1e15 else f"{value:.1f}"
