"""The sorties of an allocation: hidden polylines, one per battery, as MAVLink flies them.

A route of viewpoints is flown in sorties by the greedy split the methods
planned with (`sortie_split`); each sortie takes off from a base (or, the
first, from its start), flies its viewpoints and lands at the base nearest its
last one (`_landings`). `make_sorties` finds each sortie's hidden polyline on
the travel graph, rounds it as MAVLink carries it, keeps only the vertices a
mission must fly, and proves every leg again, rounded, by the mission check's
own tests.
"""

from dataclasses import dataclass
from typing import Optional

import numpy as np

from common.errors import InputError
from planner.exposure import segments_clear, segments_hidden

from .coverage.model import landing_bases
from .coverage.model.routes import walked
from .fleet import Profile, stop_time
from .launch import SAME_PLACE_M, above_launch, fleet_bases, launch_tops


def sortie_split(prep, routes) -> list:
    """Per UAV, the sortie of each visit: the greedy split the methods planned with
    (`coverage.model.routes.walk`; all 0 with an unlimited battery)."""
    return [walked(np.asarray(route, np.int64), prep.travel, prep.battery(r),
                   prep.has_launch)[1] for r, route in enumerate(routes)]


def _landings(ctx, problem, starts, route, of, r) -> list:
    """The ground point each sortie of UAV r's route lands at (index: the sortie of
    `sortie_split`): the base nearest its last viewpoint (`coverage.model.
    landing_bases`) where the fleet's bases are several, else its own; the start's
    flight home without a visit (sortie 0 before a route of later sorties) lands
    at its own."""
    own = starts[r].launch
    n = int(of[-1]) + 1 if len(of) else 1
    if problem.bases_back is None:
        return [own] * n
    bases, at = fleet_bases(ctx, starts), landing_bases(problem)
    out = [own] * n
    for e, j in zip(route, of):
        out[int(j)] = bases[at[e]]       # the last visit of each sortie decides
    return out


@dataclass
class Sortie:
    """One flight of a UAV's route, takeoff to touchdown (one battery)."""

    uav: int
    number: int          # 1, 2, ... along the route
    visits: list         # viewpoint ids photographed, in order
    poly: np.ndarray     # its hidden polyline (projected x, y, alt AMSL), rounded and proven
    snap: np.ndarray     # the polyline vertex of each visit
    first: bool          # the route's first: from its start (the others from a base)
    base: Optional[np.ndarray] = None   # ground point it takes off from (x, y, ground AMSL)
    lands: Optional[np.ndarray] = None  # ground point it lands at (None: no base)
    stops: Optional[np.ndarray] = None  # the vertex of each visit and check-in, in order


@dataclass(frozen=True)
class CheckIn:
    """A waypoint in radio contact that a route flies to and on from without a
    photograph (``--max-silence``, `planner.link.checkins`): before the route's visit
    ``before`` (its index; the route's length: after its last), in its sortie
    ``sortie`` (that of `sortie_split`)."""

    before: int
    sortie: int
    xyz: np.ndarray


def flown_stops(route, of, checks=()) -> list:
    """(sortie, viewpoint id or -1, check-in or None) of each stop of one route, in
    the order flown: its visits, and its `CheckIn`s (in the order given, by
    ``before``) where they go."""
    out, k = [], 0
    for q in range(len(route) + 1):
        while k < len(checks) and checks[k].before == q:
            out.append((checks[k].sortie, -1, checks[k]))
            k += 1
        if q < len(route):
            out.append((int(of[q]), int(route[q]), None))
    return out


def _sortie_points(ctx, route, start, of, lands, checks=()) -> list:
    """[(visits, points, base, lands, visit or not per stop)] per sortie of one route:
    each from its start (the first) or the point above the base the one before
    landed at, through its stops (viewpoints and ``checks``), to the point above the
    base it lands at (``lands``: per sortie, `_landings`). ``of``: the sortie of each
    visit (0: the flight under way at the start; a vehicle in flight whose battery
    cannot take it to its first viewpoint flies home first, a sortie without
    visits)."""
    vp = ctx.viewpoints.xyz
    flown = flown_stops(route, of, checks)
    if start is None:
        return [(list(route), np.array([vp[e] if e >= 0 else c.xyz for _, e, c in flown],
                                       float).reshape(-1, 3), None, None,
                 np.array([e >= 0 for _, e, _ in flown], bool))]
    out, base = [], start.launch
    for j in range(int(of[-1]) + 1 if len(of) else 1):
        stops = [(e, c) for o, e, c in flown if o == j]
        if not stops and j > 0:
            continue
        p = [start.xyz if j == 0 else above_launch(ctx, base)] + \
            [vp[e] if e >= 0 else c.xyz for e, c in stops]
        if lands[j] is not None:
            p.append(above_launch(ctx, lands[j]))
        out.append(([e for e, _ in stops if e >= 0], np.array(p, float).reshape(-1, 3), base,
                    lands[j], np.array([e >= 0 for e, _ in stops], bool)))
        base = lands[j]
    return out


def make_sorties(ctx, problem, routes, starts, progress=None, sortie_of=None,
                 checks=None) -> list:
    """The `Sortie`s of every route: hidden polylines through its viewpoints, one
    per battery (``sortie_of[r]``: the sortie of each visit; default one flight),
    and through its `CheckIn`s (``checks[r]``, ordered by ``before``).

    Waypoints are rounded as MAVLink carries them (1e-7 degrees, float32
    altitudes) and every leg is proven again, rounded, by the same tests the
    mission check runs (`planner.exposure.segments_hidden`, `segments_clear`)."""
    wanted = []
    for r, route in enumerate(routes):
        start = starts[r] if starts else None
        if route or start is not None:    # a UAV without viewpoints takes off and lands
            of = np.zeros(len(route), int) if sortie_of is None else sortie_of[r]
            lands = None if start is None else _landings(ctx, problem, starts, route, of, r)
            wanted += [(r, *w) for w in _sortie_points(ctx, route, start, of, lands,
                                                        checks[r] if checks else ())]
    found = ctx.graph.route_polylines([w[2] for w in wanted],
                                      (lambda f: progress(0.8 * f)) if progress else None)
    sorties, number = [], {}
    for n, ((r, visits, _, base, lands, is_visit), got) in enumerate(zip(wanted, found)):
        if got is None:
            raise InputError("plan", f"UAV {r + 1}: two of its viewpoints are not joined by a "
                                     "hidden path (a defect: the planner only pairs reachable "
                                     "viewpoints)")
        poly, stops = got
        poly, stops = _fewest_vertices(ctx, _rounded_for_mavlink(ctx, poly), stops)
        _prove(ctx, r, poly)
        if progress is not None:
            progress(0.8 + 0.2 * (n + 1) / len(wanted))
        number[r] = number.get(r, 0) + 1
        middle = np.asarray(stops[1:len(is_visit) + 1] if starts else stops[:len(is_visit)],
                            np.int64)
        sorties.append(Sortie(r, number[r], visits, poly, middle[is_visit], number[r] == 1,
                              base, lands, middle))
    return sorties


def one_visit_flight_s(ctx, base, viewpoints, lands) -> np.ndarray:
    """Seconds of flight of a sortie out of ``base`` (a ground point) to each of
    ``viewpoints`` (ids) alone, down at ``lands[i]`` (ground points): its polyline
    made as `make_sorties` makes one (rounded for MAVLink, the vertices a mission
    flies) and timed as the fleet clock times it, holds aside. The search's travel
    times leave out the stops at the waypoints and the slow metres of the takeoff
    and the landing: on a 3-min battery the round trips took up to 40 % more
    than they said. inf where no hidden path joins them."""
    lands = np.asarray(lands, float).reshape(-1, 3)
    top = above_launch(ctx, base)
    ends, where = np.unique(lands, axis=0, return_inverse=True)
    above = launch_tops(ctx.graph, ends[:, :2])[where.ravel()]
    vp = ctx.viewpoints.xyz
    found = ctx.graph.route_polylines([np.array([top, vp[e], a])
                                       for e, a in zip(viewpoints, above)])
    stop_s, out = stop_time(vars(ctx.scenario)), np.full(len(lands), np.inf)
    for i, got in enumerate(found):
        if got is not None:
            poly, _ = _fewest_vertices(ctx, _rounded_for_mavlink(ctx, got[0]), got[1])
            out[i] = Profile.of_route(poly, ctx.travel_params, launch=base, land=lands[i],
                                      stop_s=stop_s).duration.sum()
    return out


def uav_polylines(sorties, n_uavs) -> list:
    """Per UAV, its sorties' polylines one after the other (for maps and checks)."""
    out = [[] for _ in range(n_uavs)]
    for f in sorties:
        out[f.uav].append(f.poly)
    return [np.vstack(p) if p else np.zeros((0, 3)) for p in out]


def _fewest_vertices(ctx, poly, stops) -> tuple:
    """The polyline with only the vertices a mission must fly: the ``stops`` (start,
    snapshots, end), and a vertex between them only where the straight leg past it
    fails the planned legs' proofs (`TravelGraph.legs_ok`); a vertex repeating the
    one before is one. A vehicle stops at each waypoint it flies, so these are
    the waypoints its missions carry and its schedule counts (`missions.segments`
    finds nothing more to leave out)."""
    must = np.zeros(len(poly), bool)
    must[stops] = True
    keep = [0]
    for j in range(1, len(poly)):
        if np.all(np.abs(poly[j] - poly[keep[-1]]) < SAME_PLACE_M):
            if must[j]:
                keep[-1] = j          # the stop is the one flown
            continue
        keep.append(j)
    out = [keep[0]]
    for i, j in enumerate(keep[1:-1], start=1):
        if must[j] or not ctx.graph.legs_ok(poly[out[-1]], poly[keep[i + 1]])[0]:
            out.append(j)
    if len(keep) > 1:
        out.append(keep[-1])
    index = np.full(len(poly), -1, np.int64)
    index[out] = np.arange(len(out))
    # a stop merged into the same place as another keeps that one's index
    for j in np.flatnonzero(must & (index < 0)):
        index[j] = index[max(k for k in out if k <= j)] if any(k <= j for k in out) else 0
    return poly[out], index[stops]


def _rounded_for_mavlink(ctx, poly) -> np.ndarray:
    """The polyline as MAVLink carries it: latitude and longitude in 1e-7 degrees,
    altitudes as float32 rounded down (lower is never less hidden; the planner
    keeps a clearance margin far larger than a float32 step)."""
    lon, lat = ctx.terrain.to_lonlat(poly[:, 0], poly[:, 1])
    lon = np.round(np.asarray(lon, float) * 1e7) / 1e7
    lat = np.round(np.asarray(lat, float) * 1e7) / 1e7
    alt = poly[:, 2].astype(np.float32)
    alt = np.where(alt.astype(float) > poly[:, 2], np.nextafter(alt, np.float32(-np.inf)), alt)
    x, y = ctx.terrain.from_lonlat(lon, lat)
    return np.stack([np.asarray(x, float), np.asarray(y, float), alt.astype(float)], axis=1)


def _prove(ctx, r, poly) -> None:
    """Every leg hidden and clear, by the mission check's own tests."""
    if len(poly) < 2:
        return
    ok = segments_hidden(ctx.surface, poly[:-1], poly[1:]) & \
        segments_clear(ctx.surface, poly[:-1], poly[1:])
    if not ok.all():
        n = int(np.flatnonzero(~ok)[0])
        raise InputError("plan", f"UAV {r + 1}: leg {n + 1} of its route fails the hidden and "
                                 "clearance proof once rounded for MAVLink (a planner defect: "
                                 "please report it with the scenario)")
