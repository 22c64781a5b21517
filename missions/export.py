"""Write the mission files of a plan: every mission is built and checked first,
so a refused plan writes nothing; each file is then written atomically.

Per vehicle ``vehicle-<id>.plan`` (QGroundControl) and ``vehicle-<id>.waypoints``
(QGC WPL 110), or per sortie of a vehicle that flies several
``vehicle-<id>-sortie-<n>.plan`` and ``.waypoints``; for the whole fleet
``routes.geojson`` and ``routes.kml``.

A folder holds one firmware's missions: nothing is written where that would
leave mission files of the other firmware beside the new ones, or under a
``plan.json`` that says otherwise (`check_folder`); exported into the plan's own
folder, its ``plan.json`` is given the firmware written.
"""

import re
from pathlib import Path
from typing import Optional

from autopilots import NAMES, firmware_of, profile
from common.errors import InputError
from planner.plan import PLAN_FILE, Plan

from . import FORMATS, geo, qgc, wpl
from .build import MissionOptions, firmware_profile, plan_missions
from .check import check_mission
from .returns import rally_points

ROUTES_GEOJSON = "routes.geojson"
ROUTES_KML = "routes.kml"
MISSION_FORMATS = ("plan", "waypoints")  # the formats with one mission file per vehicle
_VEHICLE_FILE = re.compile(r"vehicle-\d+(-sortie-\d+)?\.(plan|waypoints)")


def vehicle_file(directory, vehicle_id, suffix, sortie=0) -> Path:
    """``vehicle-<id>.<suffix>``, or ``vehicle-<id>-sortie-<n>.<suffix>`` for one
    sortie of a vehicle that flies several."""
    tail = f"-sortie-{sortie}" if sortie else ""
    return Path(directory) / f"vehicle-{vehicle_id}{tail}.{suffix}"


def export_plan_dir(directory, plan, firmware: Optional[str] = None, surface=None,
                    options: Optional[MissionOptions] = None, formats=FORMATS,
                    fences: bool = True, plan_dir=None) -> list:
    """Write ``formats`` of ``plan`` into ``directory``; [(path, one-line description)].

    With a ``surface`` (planner.exposure.ExposureSurface) every mission is proven
    hidden and clear first (`missions.check.check_mission`, clearance from the
    plan); ``surface=None`` skips that proof. ``fences``: the outposts' ranges as
    exclusion circles in the ``.plan`` files. ``plan_dir``: the folder ``plan``
    was loaded from; written into it, its ``plan.json`` is given ``firmware`` (last).
    Nothing is written where the folder would then disagree (`check_folder`).
    """
    firmware = export_firmware(plan, firmware)
    check_folder(directory, plan, firmware, formats, plan_dir)
    missions = plan_missions(plan, firmware, options)
    if surface is not None:
        for mission in missions:
            check_mission(mission, surface, plan.params.get("clearance_m"))
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    speed = plan.params.get("speed_mps")
    rally = rally_points(plan, missions)     # the bases, proven with the missions above
    written = []
    for mission in missions:
        written += _vehicle_files(directory, mission, plan, speed, formats, fences, rally)
    if "geojson" in formats:
        geo.write_geojson(directory / ROUTES_GEOJSON, plan)
        written.append((directory / ROUTES_GEOJSON,
                        "routes, snapshot points and outposts (GeoJSON, altitudes AMSL)"))
    if "kml" in formats:
        geo.write_kml(directory / ROUTES_KML, plan)
        written.append((directory / ROUTES_KML, "routes and outposts for Google Earth (KML)"))
    if _in_place(directory, plan_dir) and plan.params.get("firmware") != firmware:
        plan.params["firmware"] = firmware       # its mission files are this firmware's now
        written.append((plan.save(directory), f"its firmware is now {firmware}"))
    return written


def export_firmware(plan, firmware: Optional[str] = None) -> str:
    """The firmware an export writes: ``firmware``, else the plan's, else the default
    (`autopilots.firmware_of`)."""
    return firmware_profile(firmware_of(plan.params, firmware)).name


def check_formats(formats) -> None:
    unknown = sorted(set(formats) - set(FORMATS), key=str)
    if unknown:
        raise InputError("--format", f"unknown format {unknown[0]!r}; known: {', '.join(FORMATS)}")


def check_folder(directory, plan, firmware: str, formats=FORMATS, plan_dir=None) -> None:
    """InputError naming ``directory`` if writing ``formats`` of ``plan`` for
    ``firmware`` there would leave it holding two firmwares' missions: a mission
    file (``vehicle-<id>[-sortie-<n>].plan|.waypoints``) this export does not
    rewrite that is the other firmware's, or a ``plan.json`` of the other firmware
    that is not the plan's own (``plan_dir``; that one is rewritten). A file that
    does not say (an unmarked ``.waypoints`` without camera commands, an unreadable
    one) is taken for the firmware the folder's ``plan.json`` says. Reads only."""
    from .sources import mission_file_firmware

    check_formats(formats)
    directory = Path(directory)
    if not directory.is_dir():
        return
    title = profile(firmware).title
    claimed = None                                   # what the folder says it holds
    if (directory / PLAN_FILE).is_file():
        if _in_place(directory, plan_dir):
            claimed = plan.params.get("firmware")
        else:
            claimed = Plan.load(directory).params.get("firmware")
            if claimed is not None and claimed != firmware:
                raise InputError(directory, f"holds the {PLAN_FILE} of {_a(claimed)} plan: "
                                            f"{title} missions written here would disagree "
                                            "with it; write them into another folder")
    missions = plan_missions(plan, firmware)
    names = {fmt: {vehicle_file(".", m.vehicle_id, fmt, m.sortie).name for m in missions}
             for fmt in MISSION_FORMATS}
    written = set().union(*(names[fmt] for fmt in MISSION_FORMATS if fmt in formats))
    stale = []
    for path in sorted(directory.iterdir()):
        if path.name in written or not _VEHICLE_FILE.fullmatch(path.name) or \
                not path.is_file():
            continue
        try:
            own = mission_file_firmware(path)
        except InputError:
            own = None
        if (own or claimed) not in (None, firmware):
            stale.append(path.name)
    if not stale:
        return
    other = profile(next(n for n in NAMES if n != firmware)).title
    shown = _list(stale)
    missing = [fmt for fmt in MISSION_FORMATS if fmt not in formats
               and any(name in names[fmt] for name in stale)]
    orphans = [name for name in stale if not any(name in names[f] for f in MISSION_FORMATS)]
    hint = " and ".join(([f"add {','.join(missing)} to --format to rewrite them"]
                         if missing else [])
                        + ([f"remove {'them' if len(orphans) == len(stale) else _list(orphans)}"]
                           if orphans else []))
    where = "in place" if _in_place(directory, plan_dir) else "here"
    raise InputError(directory, f"writing {title} missions {where} would leave {other} ones "
                                f"beside them ({shown}): {hint}, or write into another "
                                "folder with -o DIR")


def _list(names) -> str:
    return ", ".join(names[:3]) + (f" and {len(names) - 3} more" if len(names) > 3 else "")


def _in_place(directory, plan_dir) -> bool:
    return plan_dir is not None and Path(directory).resolve() == Path(plan_dir).resolve()


def _a(firmware: str) -> str:
    title = profile(firmware).title
    return ("an " if title[:1].lower() in "aeiou" else "a ") + title


def _vehicle_files(directory, mission, plan, speed, formats, fences, rally=()) -> list:
    out = []
    n = len(mission.items)
    what = f"{mission.name}: {n} items, {mission.firmware}"
    home = _home(plan, mission)
    if "plan" in formats:
        path = vehicle_file(directory, mission.vehicle_id, "plan", mission.sortie)
        qgc.write_plan_file(path, mission, speed, plan.outposts if fences else (),
                            home=home, rally=rally)
        out.append((path, f"{what} (QGroundControl .plan)"))
    if "waypoints" in formats:
        path = vehicle_file(directory, mission.vehicle_id, "waypoints", mission.sortie)
        wpl.write_waypoints(path, mission.items, mission.firmware, home=home)
        out.append((path, f"{what} (QGC WPL 110: Mission Planner, MAVProxy)"))
    return out


def _home(plan, mission):
    """Where ``mission``'s vehicle arms (lat, lon, ground AMSL): the base of its sortie
    (a later sortie may take off from another base than the first), None without one."""
    route = next((v for v in plan.vehicles if v.id == mission.vehicle_id), None)
    if route is None:
        return None
    parts = route.sortie_routes()
    part = parts[mission.sortie - 1] if 0 < mission.sortie <= len(parts) else route
    if part.launch is None:
        return None
    return (part.launch.lat, part.launch.lon, part.launch.alt_amsl)
