"""``QGC WPL 110`` waypoint files (Mission Planner, MAVProxy): writer and reader.

One header line ``QGC WPL 110``, then one tab-separated line per item:
``seq current frame command param1 param2 param3 param4 x y z autocontinue``,
x / y in degrees for global frames. The file holds exactly the items uploaded,
so what line 0 is depends on the firmware's `autopilots` profile: home where
the firmware keeps home as item 0 (ArduPilot); otherwise the first real item
(PX4: a program that takes line 0 for home should be given the ``.plan``).
"""

import math

from common.errors import InputError
from common.fileio import write_text_atomic

from .items import MissionItem

HEADER = "QGC WPL 110"


def waypoints_text(items) -> str:
    lines = [HEADER]
    for it in items:
        values = [f"{int(it.seq)}", f"{int(it.current)}", f"{int(it.frame)}", f"{int(it.command)}",
                  *(_number(v) for v in (it.param1, it.param2, it.param3, it.param4)),
                  _number(it.x, 9 if it.is_global else None),
                  _number(it.y, 9 if it.is_global else None),
                  _number(it.z), f"{int(it.autocontinue)}"]
        lines.append("\t".join(values))
    return "\n".join(lines) + "\n"


def write_waypoints(path, items) -> None:
    write_text_atomic(path, waypoints_text(items))


def read_waypoints(path) -> list:
    """The items of a ``QGC WPL 110`` file, in file order."""
    try:
        with open(path, encoding="utf-8") as f:
            text = f.read()
    except FileNotFoundError:
        raise InputError(path, "no such file") from None
    except UnicodeDecodeError:
        raise InputError(path, "not a QGC WPL 110 file (not text)") from None
    return parse_waypoints(text, path)


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
