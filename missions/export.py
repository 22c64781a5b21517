"""Write the mission files of a plan: every mission is built and checked first,
so a refused plan writes nothing; each file is then written atomically.

Per vehicle ``vehicle-<id>.plan`` (QGroundControl) and ``vehicle-<id>.waypoints``
(QGC WPL 110), or per sortie of a vehicle that flies several
``vehicle-<id>-sortie-<n>.plan`` and ``.waypoints``; for the whole fleet
``routes.geojson`` and ``routes.kml``.
"""

from pathlib import Path
from typing import Optional

from autopilots import ARDUPILOT
from common.errors import InputError

from . import FORMATS, geo, qgc, wpl
from .build import MissionOptions, firmware_profile, plan_missions
from .check import check_mission

ROUTES_GEOJSON = "routes.geojson"
ROUTES_KML = "routes.kml"


def vehicle_file(directory, vehicle_id, suffix, sortie=0) -> Path:
    """``vehicle-<id>.<suffix>``, or ``vehicle-<id>-sortie-<n>.<suffix>`` for one
    sortie of a vehicle that flies several."""
    tail = f"-sortie-{sortie}" if sortie else ""
    return Path(directory) / f"vehicle-{vehicle_id}{tail}.{suffix}"


def export_plan_dir(directory, plan, firmware: Optional[str] = None, surface=None,
                    options: Optional[MissionOptions] = None, formats=FORMATS,
                    fences: bool = True) -> list:
    """Write ``formats`` of ``plan`` into ``directory``; [(path, one-line description)].

    With a ``surface`` (planner.exposure.ExposureSurface) every mission is proven
    hidden and clear first (`missions.check.check_mission`, clearance from the
    plan); ``surface=None`` skips that proof. ``fences``: the outposts' ranges as
    exclusion circles in the ``.plan`` files.
    """
    firmware = firmware_profile(firmware or plan.params.get("firmware") or ARDUPILOT).name
    unknown = sorted(set(formats) - set(FORMATS))
    if unknown:
        raise InputError("--format", f"unknown format {unknown[0]!r}; known: {', '.join(FORMATS)}")
    missions = plan_missions(plan, firmware, options)
    if surface is not None:
        for mission in missions:
            check_mission(mission, surface, plan.params.get("clearance_m"))
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    speed = plan.params.get("speed_mps")
    written = []
    for mission in missions:
        written += _vehicle_files(directory, mission, plan, speed, formats, fences)
    if "geojson" in formats:
        geo.write_geojson(directory / ROUTES_GEOJSON, plan)
        written.append((directory / ROUTES_GEOJSON,
                        "routes, snapshot points and outposts (GeoJSON, altitudes AMSL)"))
    if "kml" in formats:
        geo.write_kml(directory / ROUTES_KML, plan)
        written.append((directory / ROUTES_KML, "routes and outposts for Google Earth (KML)"))
    return written


def _vehicle_files(directory, mission, plan, speed, formats, fences) -> list:
    out = []
    n = len(mission.items)
    what = f"{mission.name}: {n} items, {mission.firmware}"
    if "plan" in formats:
        path = vehicle_file(directory, mission.vehicle_id, "plan", mission.sortie)
        qgc.write_plan_file(path, mission, speed, plan.outposts if fences else (),
                            home=_home(plan, mission.vehicle_id))
        out.append((path, f"{what} (QGroundControl .plan)"))
    if "waypoints" in formats:
        path = vehicle_file(directory, mission.vehicle_id, "waypoints", mission.sortie)
        wpl.write_waypoints(path, mission.items, mission.firmware,
                            home=_home(plan, mission.vehicle_id))
        out.append((path, f"{what} (QGC WPL 110: Mission Planner, MAVProxy)"))
    return out


def _home(plan, vehicle_id):
    """The launch point (lat, lon, ground AMSL) of a vehicle, if it has one."""
    route = next((v for v in plan.vehicles if v.id == vehicle_id), None)
    if route is None or route.launch is None:
        return None
    return (route.launch.lat, route.launch.lon, route.launch.alt_amsl)
