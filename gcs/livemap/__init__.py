"""`gcs fly --map`: a live map of the flight in a web browser, served from this machine.

    live = LiveMap(flight, ctx, host="127.0.0.1", port=8750).start()
    print(live.url)           # open it in a browser
    ...                       # flight.run(...)
    live.stop()

For those without QGroundControl. The page uses Leaflet (vendored in
``static/leaflet``, BSD-2-Clause; nothing is fetched at run time: field laptops
are offline) over the plan's own base layer (`gcs.livemap.base`: hillshade and
hidden ceiling, reprojected to Web Mercator). It shows the outposts with their
names and ranges, the planned routes, the bases, the area polygon when the plan
has one, and live: each vehicle's position and track, the snapshots taken,
losses and the re-planned routes as they happen, a status table (altitudes
AMSL and above home) and the last events. A vehicle down between two sorties
gets a "battery swapped" button: the operator's word, as on the terminal,
taken only from a browser on this machine.

The server is the standard library's threaded HTTP server on loopback by
default (``--map HOST:PORT`` to share it on a network you trust: it has no
authentication). The page polls two JSON documents: ``plan.json`` once (what
does not change) and ``state.json`` every second (`Flight` read under the
monitor's lock). Colours are `common.colours`, as in the PNG, KML and GeoJSON.
"""

import json
import math
import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources
from pathlib import Path

from common.colours import BASE_COLOUR, OUTPOST_COLOUR, vehicle_colour
from gcs.monitor import mission_items, shown_item

STATIC = "static"
DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8750
TRACK_POINTS = 1500                    # most track points sent per vehicle (decimated)
EVENTS = 12
LOOPBACK = frozenset({"127.0.0.1", "::1", "::ffff:127.0.0.1"})
TYPES = {".html": "text/html; charset=utf-8", ".js": "text/javascript; charset=utf-8",
         ".css": "text/css; charset=utf-8", ".png": "image/png", ".json": "application/json",
         ".txt": "text/plain; charset=utf-8", "": "text/plain; charset=utf-8"}


def parse_address(text: str | None) -> tuple:
    """``HOST:PORT``, ``PORT`` or None (the default, loopback) -> (host, port)."""
    if text is None or text == "":
        return DEFAULT_HOST, DEFAULT_PORT
    host, sep, port = str(text).rpartition(":")
    if not sep:
        host, port = DEFAULT_HOST, text
    if not port.isdigit() or not 0 <= int(port) <= 65535:
        raise ValueError(f"{text}: expected HOST:PORT or PORT (e.g. 127.0.0.1:{DEFAULT_PORT})")
    return host.strip("[]") or DEFAULT_HOST, int(port)


class LiveMap:
    """The web server of one flight."""

    def __init__(self, flight, ctx, host: str = DEFAULT_HOST, port: int = DEFAULT_PORT,
                 area=None):
        """``flight``: a `gcs.flight.Flight` (read, never changed); ``ctx``: its plan's
        context (terrain and surface for the base layer); ``area``: polygons of the
        plan's area file (`planner.terrain.area.read_area`), drawn when given."""
        from gcs.livemap.base import base_layer, ceiling_scale_png

        self.flight = flight      # read; written only by the operator's swap (`do_POST`)
        base = base_layer(ctx.terrain, ctx.surface)
        self._files = {"/base.png": (base["png"], TYPES[".png"]),
                       "/ceiling-scale.png": (ceiling_scale_png(base["ceiling_agl_m"][1]),
                                              TYPES[".png"])}
        self._plan = plan_document(flight.plan, ctx, base, area)
        self._server = ThreadingHTTPServer((host, port), self._handler())
        self._server.daemon_threads = True
        self._thread = None

    @property
    def url(self) -> str:
        host, port = self._server.server_address[:2]
        shown = "127.0.0.1" if host in ("0.0.0.0", "") else host
        return f"http://{shown}:{port}/"

    def start(self) -> "LiveMap":
        self._thread = threading.Thread(target=self._server.serve_forever, daemon=True,
                                        name="live-map")
        self._thread.start()
        return self

    def stop(self) -> None:
        self._server.shutdown()
        self._server.server_close()
        if self._thread is not None:
            self._thread.join(timeout=2)

    # -- documents -----------------------------------------------------------------------
    def plan_json(self) -> bytes:
        return json.dumps(self._plan, allow_nan=False).encode()

    def state_json(self) -> bytes:
        return json.dumps(flight_state(self.flight), allow_nan=False).encode()

    def _handler(self):
        live = self

        class Handler(BaseHTTPRequestHandler):
            def do_GET(self):  # noqa: N802 - the standard library's name
                path = self.path.split("?", 1)[0]
                try:
                    if path == "/plan.json":
                        body, kind = live.plan_json(), TYPES[".json"]
                    elif path == "/state.json":
                        body, kind = live.state_json(), TYPES[".json"]
                    elif path in live._files:
                        body, kind = live._files[path]
                    else:
                        body, kind = _static(path)
                except FileNotFoundError:
                    self.send_error(404)
                    return
                self.send_response(200)
                self.send_header("Content-Type", kind)
                self.send_header("Content-Length", str(len(body)))
                self.send_header("Cache-Control", "no-store")
                self.end_headers()
                self.wfile.write(body)

            def do_POST(self):  # noqa: N802 - the standard library's name
                """``/swap`` with ``{"sysid": N}``: the operator's word that vehicle N's
                battery is swapped, taken only from this machine (the page has no
                authentication; a map shared on a network only shows)."""
                if self.path != "/swap":
                    self.send_error(404)
                    return
                if self.client_address[0] not in LOOPBACK:
                    self.send_error(403, "confirm a swap on the ground station's machine")
                    return
                try:
                    length = int(self.headers.get("Content-Length", 0))
                    sysid = int(json.loads(self.rfile.read(min(length, 1024)))["sysid"])
                except (ValueError, KeyError, TypeError):
                    self.send_error(400, 'expected {"sysid": N}')
                    return
                if not live.flight.confirm_swap(sysid, " (live map)"):
                    self.send_error(404, f"no vehicle {sysid}")
                    return
                self.send_response(204)
                self.end_headers()

            def log_message(self, *args):        # quiet: the flight's own log is the log
                pass

        return Handler


def _static(path: str) -> tuple:
    """A file under ``static/`` (``/`` is index.html); FileNotFoundError otherwise."""
    rel = "index.html" if path in ("/", "/index.html") else path.lstrip("/")
    parts = Path(rel).parts
    if not parts or any(p in ("..", "") or p.startswith(".") for p in parts):
        raise FileNotFoundError(path)
    node = resources.files(__package__).joinpath(STATIC, *parts)
    if not node.is_file():
        raise FileNotFoundError(path)
    return node.read_bytes(), TYPES.get(Path(rel).suffix, TYPES[""])


# -- what the page shows -------------------------------------------------------------------
def _finite(value, digits=None):
    if value is None:
        return None
    value = float(value)
    if not math.isfinite(value):
        return None
    return round(value, digits) if digits is not None else value


def plan_document(plan, ctx, base, area=None) -> dict:
    """What does not change during the flight."""
    outposts = []
    for n, o in enumerate(plan.outposts):
        if not (math.isfinite(float(o["lon"])) and math.isfinite(float(o["lat"]))):
            continue
        outposts.append({"name": o.get("name") or f"outpost {n + 1}", "lat": o["lat"],
                         "lon": o["lon"], "height_m": _finite(o.get("height_m")),
                         "range_m": _finite(o.get("range_m"))})
    routes = []
    for v in plan.vehicles:
        routes.append({
            "vehicle": v.id, "colour": vehicle_colour(v.id),
            "points": [[w.lat, w.lon] for w in v.waypoints],
            "snapshots": [[w.lat, w.lon] for w in v.waypoints if w.snapshot],
            "launch": None if v.launch is None else [v.launch.lat, v.launch.lon,
                                                     v.launch.alt_amsl],
            "coverage_time_s": _finite(v.coverage_time_s, 1)})
    polygons = [[[[float(lat), float(lon)] for lon, lat in ring] for ring in polygon]
                for polygon in (area or [])]
    return {"title": f"{plan.method.upper()} plan, {len(plan.vehicles)} UAVs, "
                     f"k = {plan.metrics.get('k', 0)}",
            "base": {"url": "base.png", "bounds": base["bounds"],
                     "ceiling_agl_m": base["ceiling_agl_m"], "scale": "ceiling-scale.png"},
            "outposts": outposts, "routes": routes, "area": polygons,
            "colours": {"outpost": OUTPOST_COLOUR, "base": BASE_COLOUR}}


def _decimate(points, most=TRACK_POINTS):
    if len(points) <= most:
        return points
    step = math.ceil(len(points) / most)
    return points[::step] + [points[-1]]


def flight_state(flight) -> dict:
    """What the vehicles are doing now: read from the flight's monitor under its lock."""
    m = flight.monitor
    with m._lock:
        vehicles = []
        for sysid, v in sorted(m.vehicles.items()):
            s = m.links[sysid].state
            track = [[p[2], p[1]] for p in v.track]
            last = v.track[-1] if v.track else None
            vehicles.append({
                "sysid": sysid, "vehicle": v.vehicle_id, "colour": vehicle_colour(v.vehicle_id),
                "state": v.state, "mode": s.mode, "mission": v.generation,
                "item": shown_item(s, mission_items(v.mission)), "items": mission_items(v.mission),
                "position": None if last is None else [last[2], last[1]],
                "alt_amsl": _finite(None if last is None else last[3], 1),
                "alt_above_home": _finite(s.relative_alt, 1),
                "heartbeat_s": _finite(m.links[sysid].heartbeat_age(), 1),
                "track": _decimate(track),
                "snapshots": [[p.lat, p.lon] for p in v.snapshots],
                "snapshots_planned": v.snapshot_total, "snapshots_done": v.snapshots_done,
                "lost_at_s": v.lost_at_s, "lost_reason": v.lost_reason,
                "swap": flight.swap_awaited(sysid)})
        events = list(m.events[-EVENTS:])
        now = m.now()
    replans = []
    for n, r in enumerate(list(flight.retasks), start=1):
        replans.append({"n": n, "t_s": r.t_s, "routes": {
            str(sysid): [[p[1], p[0]] for p in points] for sysid, points in r.routes.items()}})
    return {"t_s": round(now, 1), "vehicles": vehicles, "replans": replans,
            "events": [_event_text(e) for e in events]}


def _event_text(e) -> str:
    who = f"vehicle {e['sysid']}: " if e.get("sysid") is not None else ""
    extra = {k: v for k, v in e.items() if k not in ("t_s", "sysid", "event")}
    tail = " " + " ".join(f"{k}={v}" for k, v in extra.items()) if extra else ""
    return f"[{e['t_s']:7.1f} s] {who}{e['event']}{tail}"


__all__ = ["DEFAULT_HOST", "DEFAULT_PORT", "LiveMap", "flight_state", "parse_address",
           "plan_document"]
