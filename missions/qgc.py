"""QGroundControl ``.plan`` files (JSON): writer and reader.

The layout is QGroundControl's own: ``fileType "Plan"``, ``version 1``, a
``mission`` (version 2) of ``SimpleItem`` entries with the seven MAVLink params
(``null`` for NaN), a ``geoFence`` and ``rallyPoints`` (version 2). As in
QGroundControl, the ``.plan`` holds no home item: home is
``plannedHomePosition``, and for a firmware that keeps home as item 0
(ArduPilot, see its `autopilots` profile) it becomes item 0 again on reading
(QGroundControl and MAVSDK insert it the same way before an upload).
``firmwareType`` is the profile's MAV_AUTOPILOT number.

The outposts' detection ranges are written as exclusion geofence circles so
QGroundControl draws them. Note that an autopilot with its fence enabled would
act on them if the fence were uploaded too.

``rallyPoints`` holds the fleet's bases and nothing else (`missions.returns`):
[lat, lon, alt] with the altitude relative to ``plannedHomePosition``, as
QGroundControl writes them and MAVSDK uploads them (MAV_FRAME_GLOBAL_RELATIVE_ALT,
MAV_CMD_NAV_RALLY_POINT).
"""

import json
import math
from dataclasses import dataclass, field
from typing import Optional

from autopilots import PROFILES, PX4, profile, profile_of_heartbeat
from autopilots.mavlink import FRAME_GLOBAL, MAV_TYPE_QUADROTOR, NAV_WAYPOINT
from common.errors import InputError
from common.fileio import write_text_atomic

from .build import firmware_profile
from .items import MissionItem, renumber

#: firmware name -> .plan firmwareType (MAV_AUTOPILOT)
MAV_AUTOPILOT = {name: p.mav_autopilot for name, p in PROFILES.items()}
ALTITUDE_MODE_ABSOLUTE = 2  # QGroundControl's AltMode: 1 relative, 2 absolute (AMSL)
GROUND_STATION = "hidden-coverage-gcs"
DEFAULT_SPEED_MPS = 5.0  # cruiseSpeed / hoverSpeed when the mission sets no speed


@dataclass
class QgcPlan:
    """What a ``.plan`` file says: the mission items as uploaded, and the rest."""

    items: list  # [MissionItem]; for ArduPilot item 0 is home
    firmware: str
    home: Optional[tuple]  # (lat, lon, alt AMSL) = plannedHomePosition
    cruise_speed_mps: Optional[float] = None
    hover_speed_mps: Optional[float] = None
    fence_circles: list = field(default_factory=list)  # [(lat, lon, radius_m, inclusion)]
    rally_points: list = field(default_factory=list)  # [(lat, lon, alt above home)]
    declared: Optional[str] = None  # the firmware its firmwareType names (None: neither)


# --- writer ---------------------------------------------------------------------------------

def plan_json(mission, speed_mps=None, outposts=(), home=None, rally=()) -> dict:
    """The ``.plan`` document of a `missions.build.VehicleMission`.

    ``home``: (lat, lon, alt AMSL) where the firmware has no home item (PX4),
    default the first position item (ArduPilot's is its item 0). ``outposts``:
    plan.outposts dicts; those with a range become
    exclusion circles. ``rally``: [(lat, lon, alt AMSL)], the fleet's bases
    (`missions.returns.rally_points`), written relative to home.
    """
    items = list(mission.items)
    autopilot = profile(mission.firmware)
    if autopilot.home_item and items:
        home_item, items = items[0], items[1:]
        home = (home_item.x, home_item.y, home_item.z)  # what ArduPilot is given
    if home is None:
        first = next((it for it in items if it.is_position), None)
        home = (first.x, first.y, first.z) if first else (0.0, 0.0, 0.0)
    speed = float(speed_mps) if speed_mps else DEFAULT_SPEED_MPS
    return {
        "fileType": "Plan",
        "version": 1,
        "groundStation": GROUND_STATION,
        "mission": {
            "version": 2,
            "firmwareType": autopilot.mav_autopilot,
            "vehicleType": MAV_TYPE_QUADROTOR,
            "cruiseSpeed": speed,
            "hoverSpeed": speed,
            "globalPlanAltitudeMode": ALTITUDE_MODE_ABSOLUTE,
            "plannedHomePosition": [float(home[0]), float(home[1]), float(home[2])],
            "items": [_simple_item(it, n + 1) for n, it in enumerate(items)],
        },
        "geoFence": {"version": 2, "polygons": [], "circles": _fence_circles(outposts)},
        "rallyPoints": {"version": 2, "points": [
            [float(lat), float(lon), float(alt) - float(home[2])] for lat, lon, alt in rally]},
    }


def write_plan_file(path, mission, speed_mps=None, outposts=(), home=None, rally=()) -> None:
    doc = plan_json(mission, speed_mps, outposts, home, rally)
    write_text_atomic(path, json.dumps(doc, indent=4, allow_nan=False) + "\n")


def _simple_item(it, jump_id) -> dict:
    item = {
        "type": "SimpleItem",
        "command": int(it.command),
        "frame": int(it.frame),
        "params": [_json_number(v) for v in (it.param1, it.param2, it.param3, it.param4,
                                             it.x, it.y, it.z)],
        "autoContinue": bool(it.autocontinue),
        "doJumpId": jump_id,
    }
    if it.is_position:
        item.update({"Altitude": float(it.z), "AltitudeMode": ALTITUDE_MODE_ABSOLUTE,
                     "AMSLAltAboveTerrain": None})
    return item


def _json_number(value):
    value = float(value)
    return value if math.isfinite(value) else None


def _fence_circles(outposts) -> list:
    circles = []
    for o in outposts:
        if o.get("range_m") is None or not all(
                math.isfinite(float(o[k])) for k in ("range_m", "lat", "lon")):
            continue  # an unlimited range has no circle; an unplaced outpost none either
        circles.append({"circle": {"center": [float(o["lat"]), float(o["lon"])],
                                   "radius": float(o["range_m"])},
                        "inclusion": False, "version": 1})
    return circles


# --- reader ---------------------------------------------------------------------------------

def read_plan_file(path, firmware: Optional[str] = None) -> list:
    """The mission items of a ``.plan`` file, as they would be uploaded.

    ``firmware`` (ardupilot|px4) is the vehicle's flavour; default the file's
    ``firmwareType``. Where the firmware keeps home as item 0 (ArduPilot), home
    (``plannedHomePosition``) is item 0.
    """
    return load_plan_file(path, firmware).items


def load_plan_file(path, firmware: Optional[str] = None) -> QgcPlan:
    try:
        with open(path, encoding="utf-8") as f:
            doc = json.load(f)
    except FileNotFoundError:
        raise InputError(path, "no such file") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise InputError(path, f"not a QGroundControl plan: invalid JSON ({exc})") from None
    return parse_plan(doc, path, firmware)


def parse_plan(doc, source=".plan", firmware: Optional[str] = None) -> QgcPlan:
    if not isinstance(doc, dict) or doc.get("fileType") != "Plan":
        raise InputError(source, 'not a QGroundControl plan (fileType is not "Plan")')
    _version(doc, 1, source, "plan")
    mission = doc.get("mission")
    if not isinstance(mission, dict):
        raise InputError(source, 'no "mission" in the plan')
    _version(mission, 2, source, "mission")
    declared = profile_of_heartbeat(_int_or(mission.get("firmwareType")))
    autopilot = firmware_profile(firmware) if firmware else (declared or profile(PX4))
    firmware = autopilot.name
    home = _home(mission.get("plannedHomePosition"), source)
    try:
        items = [item for n, entry in enumerate(mission.get("items", []))
                 for item in _items_of(entry, n, source)]
    except (KeyError, TypeError, ValueError) as exc:
        raise InputError(source, f"malformed mission item: {exc!r}") from None
    if autopilot.home_item:
        if home is None:
            raise InputError(source, f"{autopilot.title} plan without plannedHomePosition")
        items.insert(0, MissionItem(0, FRAME_GLOBAL, NAV_WAYPOINT, 0, 1, 0.0, 0.0, 0.0, 0.0,
                                    *home))
    return QgcPlan(renumber(items), firmware, home, mission.get("cruiseSpeed"),
                   mission.get("hoverSpeed"), _read_fence(doc.get("geoFence"), source),
                   _read_rally(doc.get("rallyPoints"), source),
                   declared.name if declared is not None else None)


def _int_or(value, default=-1) -> int:
    try:
        return int(value)
    except (TypeError, ValueError):
        return default


def _version(obj, expected, source, what) -> None:
    if obj.get("version") != expected:
        raise InputError(source, f"{what} version {obj.get('version')!r} not supported "
                                 f"(expected {expected})")


def _home(value, source):
    if value is None:
        return None
    if not isinstance(value, list) or len(value) != 3:
        raise InputError(source, "plannedHomePosition is not [lat, lon, alt]")
    return tuple(_number(v) for v in value)


def _items_of(entry, n, source) -> list:
    kind = entry.get("type")
    if kind == "SimpleItem":
        return [_read_simple(entry)]
    if kind == "ComplexItem":
        # surveys and the like carry their generated items; take them as they are
        inner = entry.get("TransectStyleComplexItem", {}).get("Items")
        if not isinstance(inner, list):
            raise InputError(source, f"item {n + 1}: complex item "
                                     f"{entry.get('complexItemType')!r} is not supported")
        return [_read_simple(sub) for sub in inner]
    raise InputError(source, f"item {n + 1}: unknown item type {kind!r}")


def _read_simple(entry) -> MissionItem:
    params = [_number(v) for v in entry["params"]]
    if len(params) != 7:
        raise ValueError(f"params has {len(params)} values, not 7")
    return MissionItem(0, int(entry["frame"]), int(entry["command"]), 0,
                       1 if entry.get("autoContinue", True) else 0, *params)


def _number(value) -> float:
    return math.nan if value is None else float(value)


def _read_fence(fence, source) -> list:
    if fence is None:
        return []
    _version(fence, 2, source, "geoFence")
    return [(float(c["circle"]["center"][0]), float(c["circle"]["center"][1]),
             float(c["circle"]["radius"]), bool(c.get("inclusion", True)))
            for c in fence.get("circles", [])]


def _read_rally(rally, source) -> list:
    if rally is None:
        return []
    _version(rally, 2, source, "rallyPoints")
    points = rally.get("points", [])
    for n, p in enumerate(points if isinstance(points, list) else [points]):
        if not (isinstance(p, list) and len(p) == 3 and all(
                isinstance(v, (int, float)) and not isinstance(v, bool) for v in p)):
            raise InputError(source, f"rally point {n + 1} is not [lat, lon, alt]: {p!r}")
    return [tuple(float(v) for v in p) for p in points]
