"""A `Plan` becomes MAVLink mission items and the files people exchange.

- `missions.items`: `MissionItem` (one MAVLink mission item, wire conversions);
- `missions.build`: `vehicle_mission` / `plan_missions` (ArduPilot or PX4 flavour);
- `missions.check`: `check_mission` proves every leg hidden and clear;
- `missions.qgc`, `missions.wpl`: QGroundControl ``.plan`` and ``QGC WPL 110``
  writers and readers; `missions.geo`: GeoJSON and KML of the routes;
- `missions.returns`: what a firmware's own return reads from them: the fleet's
  bases as rally points, and the mission landing (`landing_gaps`);
- `missions.export`: `export_plan_dir`, all of the above for a plan directory.
"""

#: the files `missions.export` writes, by name
FORMATS = ("plan", "waypoints", "geojson", "kml")
