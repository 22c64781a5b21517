"""Batteries in flight: the watch that brings a vehicle home before its battery
runs short, the landing forecast, and the swaps between sorties.

The watch holds each sortie's draw against the plan's endurance (`watch`): a
vehicle whose battery will not last the rest of its sortie from where it is
(`left_s`, at the pace it has made along its route) with half the plan's reserve
kept is brought home early by its hidden path, its work re-planned. Between
sorties a vehicle flies its next one once its battery is fresh and, unless the
flight turns them around by itself, the operator has said it is swapped.

Whatever the plan (with an endurance or none), every battery that reports empty in
the air, and every battery failsafe the autopilot announces, is recorded
(`emptied`, `failsafes`): the flight's report counts them as problems.
"""

import re
from dataclasses import dataclass

from common.geo import distance_m
from gcs.monitor import FLYING, HOLDING, LANDED, RETURNING
from planner.travel import leg_time

from .state import homebound, next_waypoint, own_clock

#: a battery reporting this much (%) or more is fresh: the next sortie may go
FRESH_BATTERY_PCT = 95
#: fleet seconds of a sortie, and % of its battery drawn, before its rate of draw is
#: trusted by the battery watch
WATCH_AFTER_S, WATCH_AFTER_PCT = 120.0, 8
#: route seconds a vehicle must move on along its route before its pace is timed
#: from there: a hold's resume reaches it a loop or more after the ground station
#: sent it (at 100 x on a loaded machine, 20 s of its clock standing still)
MOVED_ON_S = 1.0
#: a battery drawn this many times faster than its rating (the plan's endurance) is
#: not trusted: the vehicle comes home early and stays down
FAST_DRAIN = 1.25
#: hover seconds of battery one metre of climb costs: lifting m g per metre on a hover
#: power P takes m g / P seconds of it (a 1.5 kg quadcopter hovering on 180 W: 0.08 s;
#: the simulator's battery draws so). A sortie's first minutes are mostly its takeoff
#: climb: judged by time alone, batteries drawing as rated read 1.4 times faster.
CLIMB_S_PER_M = 0.08
#: a charge reported at or below this (%) in the air is an empty battery
EMPTY_PCT = 0
#: the autopilots' battery failsafe announcements: ArduPilot's "Battery 1 is low
#: 10.50V used 2200 mAh" / "... is critical ...", PX4's "Low battery level!",
#: "Critical battery level!", "Emergency battery level!"
BATTERY_FAILSAFE_TEXT = re.compile(
    r"battery \d* ?is (low|critical)|(low|critical|emergency) battery", re.IGNORECASE)
#: how near (m) a vehicle stands to a waypoint it holds at: there it spends the hold
#: its plan gives it (autopilots hold within their 2 m acceptance radius by default)
AT_WAYPOINT_M = 5.0


@dataclass
class SortieDraw:
    """What a vehicle's battery was at its liftoff, and the metres it has climbed since
    (from its position reports, `climbed`)."""
    t0: float                    # monitor s
    own0: float | None           # its own clock
    pct0: int | None             # charge
    index: int                   # its position reports counted into ``climbed`` so far
    alt: float | None            # the altitude of the last of them
    sortie: int = 1              # which of its route's sorties
    flight_s: float = 0.0        # the sortie's planned time, takeoff to landing
    climbed: float = 0.0         # m
    forecast: bool = False       # its landing charge said (`Batteries._forecast`)

    def climb_to(self, track, until_own) -> float:
        """Metres climbed from liftoff to its own clock ``until_own``."""
        while self.index < len(track) and track[self.index][4] <= until_own:
            alt = track[self.index][3]
            if self.alt is not None:
                self.climbed += max(0.0, alt - self.alt)
            self.alt, self.index = alt, self.index + 1
        return self.climbed


def at_waypoint(w, lat, lon, alt_amsl) -> bool:
    """A vehicle at (lat, lon, alt_amsl) stands at waypoint ``w``."""
    return abs(w.alt_amsl - alt_amsl) < AT_WAYPOINT_M and \
        distance_m(lat, lon, w.lat, w.lon) < AT_WAYPOINT_M


def fresh(battery_pct) -> bool:
    """A fresh battery reported, or none reported at all (nothing to wait for)."""
    return battery_pct is None or battery_pct >= FRESH_BATTERY_PCT


class Batteries:
    """The battery watch and the swaps of one flight (see the module doc).
    ``waiting_s(sysid)``: fleet seconds until a re-plan flies it on (`Departures`)."""

    def __init__(self, state, waiting_s):
        self.state = state
        self.waiting_s = waiting_s
        self.waiting = {}         # sysid -> the sortie waiting for a fresh battery
        self.swapped = set()      # sysids whose battery swap the operator confirmed
        self._route_seen = {}     # sysid -> (route, own clock s, route time s, moved on)
        self._pace = {}           # sysid -> times slower than planned on its route so far
        self.paces = {}           # sysid -> {sortie: its pace when last timed} (the report's)
        self.late = {}            # the same, for those the watch brought home
        self._late_acted = set()  # ... in their sortie now: once a sortie (`watch`)
        self._began = {}          # sysid -> SortieDraw since its last liftoff
        self.emptied = {}         # sysid -> fleet s its battery first reported empty aloft
        self.failsafes = {}       # sysid -> [(fleet s, the autopilot's text)]
        self._listening = set()   # sysids whose battery reports `_heard` reads

    @property
    def endurance_min(self):
        return self.state.params.get("endurance_min")

    def lifted(self, sysid, route) -> None:
        """A vehicle left the ground on ``route``: its sortie's draw counts from now."""
        m = self.state.monitor
        track = m.vehicles[sysid].track
        self._began[sysid] = SortieDraw(
            m.now(), own_clock(m, sysid), m.links[sysid].state.battery_pct, len(track),
            track[-1][3] if track else None, route.waypoints[0].sortie,
            route.mission_time_s - route.takeoff_s)
        self._late_acted.discard(sysid)
        if sysid not in self._listening:
            self._listening.add(sysid)
            m.links[sysid].subscribe(lambda msg, s=sysid: self._heard(s, msg))

    def _heard(self, sysid, msg) -> None:
        """Record an empty battery reported in the air, and a battery failsafe the
        autopilot announces (from the link's reader thread): each is said as an
        event once, and the report counts it as a problem."""
        m = self.state.monitor
        kind = msg.get_type()
        aloft = m.vehicles[sysid].state in (FLYING, HOLDING, RETURNING)
        if kind in ("SYS_STATUS", "BATTERY_STATUS") and aloft and sysid not in self.emptied:
            pct = m.links[sysid].state.battery_pct
            if pct is not None and pct <= EMPTY_PCT:
                self.emptied[sysid] = m.now()
                m.event(sysid, f"battery empty in the air ({pct} % reported)")
        elif kind == "STATUSTEXT" and BATTERY_FAILSAFE_TEXT.search(msg.text or ""):
            said = self.failsafes.setdefault(sysid, [])
            if msg.text not in (text for _, text in said):      # autopilots repeat it
                said.append((round(m.now(), 1), msg.text))
                m.event(sysid, f"battery failsafe: the autopilot says '{msg.text}'")

    def short(self, sysid) -> bool:
        """Sent home by the battery watch on this sortie, or down to the plan's reserve:
        the separation guard holds the other of a pair first."""
        if not self.endurance_min:
            return False
        pct = self.state.monitor.links[sysid].state.battery_pct
        return sysid in self.state.spent or sysid in self._late_acted or \
            (pct is not None and pct <= float(self.state.params.get("reserve_pct") or 0.0))

    def watch(self) -> bool:
        """A vehicle whose battery will not last the rest of its sortie from where it
        is (`left_s`) with half the plan's reserve kept is brought home early by its
        hidden path, its work re-planned; the reserve is there for smaller surprises
        (a landing queue). The draw is the rated one (the plan's endurance), or the
        rate drawn since takeoff where that is `FAST_DRAIN` times faster (its climbs
        allowed for, `CLIMB_S_PER_M`): such a battery is not trusted, and its vehicle
        is kept down until the crew has looked at it (its work going to the others).
        One slowed instead (holds, a headwind) is re-planned on the battery it
        reports, and flies on after a swap. A vehicle with nothing left to
        photograph is on its way home already. True when a re-plan is needed."""
        endurance = self.endurance_min
        if not endurance:
            return False              # no battery model to hold the draw against
        rated = 100.0 / (60.0 * endurance)                  # % per fleet s
        m, reserve = self.state.monitor, float(self.state.params.get("reserve_pct") or 0.0)
        rate = self.state.clock.rate()                      # fleet s per wall s
        short, untrusted = [], []
        for sysid, began in list(self._began.items()):
            v, state = m.vehicles[sysid], m.links[sysid].state
            pct, own, own0, pct0 = state.battery_pct, own_clock(m, sysid), began.own0, \
                began.pct0
            # on its own clock: a busy machine slows a simulator unevenly, and the
            # fleet's rate now is not the rate since takeoff (it once read 1.5 x the
            # rated draw on a vehicle drawing as rated)
            flown = own - own0 if None not in (own, own0) else (m.now() - began.t0) * rate
            if v.state not in (FLYING, HOLDING) or None in (pct0, pct) or \
                    flown < WATCH_AFTER_S or pct0 - pct < WATCH_AFTER_PCT or \
                    not state.caught_up:        # just out of a silence: news to come
                continue
            left_s = self.left_s(sysid)
            # the charge is timed by the vehicle's clock at the first report after it
            # (no later than that): it comes once a second, positions more often, and
            # at 100 x the last position before it can be 20 s older (a 2 x drain
            # timed by the last position read as 1.3 x, batteries drawing as rated
            # as 1.25 x); what it drew since is needed too
            by = state.battery_by_s
            drained_s = by - own0 if None not in (by, own0) else flown
            if left_s is None or drained_s <= 0:
                continue
            climbed = began.climb_to(m.vehicles[sysid].track, own0 + drained_s) \
                if own0 is not None else 0.0
            drawn = (pct0 - pct) / (rated * (drained_s + CLIMB_S_PER_M * climbed))
            fast = drawn > FAST_DRAIN
            since = max(0.0, flown - drained_s)
            rest = rated * (drawn if fast else 1.0) * (left_s + since)  # % the rest needs
            need = rest + reserve / 2
            if not began.forecast:
                began.forecast = True
                self._forecast(sysid, began, pct, pct0 - rated * began.flight_s, rest,
                               reserve, drawn if fast else None, flown)
            # a late one is re-planned once a sortie: a re-plan that cannot fit its
            # battery says so, and would only be made again
            if pct >= need or (not fast and sysid in self._late_acted):
                continue
            if homebound(m, sysid):         # nothing earlier to bring it to: said once
                if sysid not in self._late_acted:
                    self._late_acted.add(sysid)
                    m.event(sysid, f"battery {pct} % on its way home: the rest ({left_s / 60:.1f}"
                                   f" min at its pace) needs {rest:.0f} %, it will land on "
                                   f"about {pct - rest:.0f} % (less than half the reserve)")
                continue
            short.append(sysid)
            said = f"battery {pct} % will not last the rest of its sortie from where it is " \
                   f"({left_s / 60:.1f} min: {need:.0f} % with half the reserve, "
            if fast:
                untrusted.append(sysid)
                m.event(sysid, said + f"drawn {drawn:.1f} times faster than rated): "
                        "brought home early by its hidden path and kept down, its work "
                        "re-planned")
            else:
                late = self.late[sysid] = self._pace.get(sysid, 1.0)
                self._late_acted.add(sysid)
                m.event(sysid, said + f"at the rated draw, {late:.1f} times slower than "
                        "planned): brought home early by its hidden path, its work "
                        "re-planned on the battery it has at that pace")
        for sysid in untrusted:
            del self._began[sysid]
        self.state.spent.update(untrusted)
        return bool(short)

    def _forecast(self, sysid, began, pct, planned, rest, reserve, drawn, flown) -> None:
        """Say once a sortie, when its draw is first trusted, what the vehicle will land
        on at that draw from where it is (``rest``: % the rest of its sortie needs),
        beside what its plan said (``planned``, from the charge it took off with): the
        operator sees a battery that will not last before the watch has to act on it."""
        at = "the rated draw" if drawn is None else f"{drawn:.1f} times the rated draw"
        self.state.monitor.event(
            sysid, f"battery {pct} % after {flown / 60:.1f} min of sortie {began.sortie}: it "
                   f"will land on about {pct - rest:.0f} % at {at} (planned {planned:.0f} "
                   f"%, reserve {reserve:.0f} %)",
            landing_pct=round(pct - rest, 1), planned_pct=round(planned, 1))

    def left_s(self, sysid):
        """Fleet seconds left in a vehicle's sortie from where it is (`_on_timeline`),
        stretched by how much slower than planned it has made its way along this
        route on its own clock (a headwind: never shrunk) since it last flew on from a
        hold (what a hold costs is in the battery it reports; a hold early on a route
        once read as 21 times slower; with the holds' spans taken out of its time
        instead, a simulated vehicle held at 100 x was once said to need 25.5 min,
        221 % of a battery, for the way home: a span's ends are known to a loop of
        the ground station, 10 s of its clock there, and its braking and speeding
        up again are in none); None past its last waypoint or without a
        position."""
        m = self.state.monitor
        v = m.vehicles[sysid]
        own = own_clock(m, sysid)
        at = self._on_timeline(sysid, own)
        if at is None:
            return None
        left = v.route.mission_time_s - at
        seen = self._route_seen.get(sysid)
        if seen is None or seen[0] is not v.route or v.state == HOLDING or \
                self.waiting_s(sysid) is not None:
            # its pace is timed from where it flies this route: not while a re-plan
            # holds it until its time (one so held read 6.8 times slower), nor while
            # the separation guard holds it
            self._route_seen[sysid] = (v.route, own, at, False)
            self._pace.pop(sysid, None)
            return left
        _, own0, at0, moved = seen
        if not moved:
            # nor until it has moved on: a resume still on its way to it (read 1.17
            # times slower, on CI, at 100 x, where it flew as planned)
            moved = at > at0 + MOVED_ON_S
            self._route_seen[sysid] = (v.route, own0 if moved else own, at0, moved)
            if not moved:
                return left
        if own - own0 >= WATCH_AFTER_S and at > at0:
            self._pace[sysid] = max(1.0, (own - own0) / (at - at0))
            left *= self._pace[sysid]
            self.paces.setdefault(sysid, {})[v.route.waypoints[0].sortie] = \
                round(self._pace[sysid], 3)
        return left

    def _on_timeline(self, sysid, own):
        """Where a vehicle is on its route's timeline (fleet s), None past its last
        waypoint or without a position: flying to its next waypoint, that one's
        planned arrival less the planner's leg time from here; standing at one its
        plan holds it at (the one it flies to or the one before: ArduPilot says it
        reached a waypoint before its hold, PX4 after), the arrival plus the time it
        has stood there, up to the hold (read as flying to the next, a 63 s hold
        timed a vehicle flying as planned 1.34 times slower)."""
        m = self.state.monitor
        v, state = m.vehicles[sysid], m.links[sysid].state
        waypoints = v.route.waypoints
        n = next_waypoint(m, sysid)
        if n >= len(waypoints) or state.lat is None or own is None:
            return None
        for w in (waypoints[i] for i in sorted({max(n - 1, 0), n})):
            if w.hold_s > 0 and at_waypoint(w, state.lat, state.lon, state.alt_amsl):
                return w.t_s + min(w.hold_s, self._stood_s(sysid, w))
        w = waypoints[n]
        to_w = leg_time(distance_m(state.lat, state.lon, w.lat, w.lon),
                        w.alt_amsl - state.alt_amsl, self.state.ctx.scenario.travel_params())
        return w.t_s - float(to_w)

    def _stood_s(self, sysid, w) -> float:
        """Own-clock seconds the vehicle has stood at waypoint ``w``: back along its
        position reports to the first there."""
        track = self.state.monitor.vehicles[sysid].track
        since = track[-1][4]
        for _, lon, lat, alt, own in reversed(track):
            if not at_waypoint(w, lat, lon, alt):
                break
            since = own
        return track[-1][4] - since

    # -- between sorties ----------------------------------------------------------------
    def swapping(self) -> set:
        """Down at its base with a sortie to fly, its fresh battery not reported yet:
        a swap that powers the autopilot down silences it for a while."""
        m = self.state.monitor
        return {s for s in self.state.awaited() if m.vehicles[s].state == LANDED
                and not fresh(m.links[s].state.battery_pct)}

    def ready(self, sysid, route, pct) -> bool:
        """The next sortie may go: the vehicle reports a fresh battery, and the
        operator confirmed the swap (`confirm_swap`) unless ``auto_turnaround``."""
        is_fresh = fresh(pct)
        confirmed = self.state.options.auto_turnaround or sysid in self.swapped
        if is_fresh and confirmed:
            return True
        if self.waiting.get(sysid) is not route:
            self.waiting[sysid] = route
            why = [] if is_fresh else [f"a fresh battery ({pct} % reported)"]
            if not confirmed:
                why.append(f"the operator's word that it is swapped (type {sysid} and Enter, "
                           "or 'battery swapped' on the live map)")
            self.state.monitor.event(sysid, f"sortie {route.waypoints[0].sortie} waits for "
                                     + " and ".join(why))
        return False

    def confirm_swap(self, sysid: int, where: str = "") -> bool:
        """The operator says vehicle ``sysid``'s battery is swapped (its next sortie may
        go once the battery it reports is fresh too); False for no such vehicle."""
        m = self.state.monitor
        if sysid not in m.vehicles:
            return False
        self.swapped.add(sysid)
        m.event(sysid, "battery swap confirmed by the operator" + where)
        return True

    def swap_awaited(self, sysid: int) -> bool:
        """Down between two sorties, waiting for the operator's word on its battery."""
        m = self.state.monitor
        return not self.state.options.auto_turnaround and sysid not in self.swapped and \
            sysid in self.state.awaited() and m.vehicles[sysid].state == LANDED
