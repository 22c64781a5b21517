"""`Flight`: one flight of a plan, coordinating the parts that each own a concern.

    report = fly(plan_dir, ["tcp:127.0.0.1:5760", ...], FlyOptions(output="flight"))

Before any connection the plan is read and every route's mission built for each
autopilot (`missions.build`) and proven hidden and clear against the plan's
surface (`missions.check.checked`: only a `CheckedMission` is uploaded), and the
fleet's separation proven again. Then: `gcs.link` finds the vehicles; the
`Preflight` checks where they stand and what their autopilots would do; each
gets its checked mission, uploaded with read-back; the `Departures` send them
off on the fleet clock; the loop (`watch`) follows them with `gcs.monitor`,
re-tasks the survivors on a loss (`gcs.retask`), flies the next sorties once the
`Batteries` allow, keeps them apart (`gcs.guard`, acting through `Holds`) and
sends the next segment of a route longer than its vehicle holds
(`gcs.segments`). At the end the `report` is written (flight.json, flight.png,
one ``.tlog`` per vehicle beside them).
"""

import threading
import time
from pathlib import Path

from autopilots import NAMES
from common.errors import InputError
from common.geo import distance_m
from gcs import commands
from gcs.busy import busy, busy_total_s
from gcs.clock import FleetClock
from gcs.guard import SeparationGuard
from gcs.link import GroundLink, LinkError
from gcs.mission_protocol import MissionError
from gcs.monitor import LANDED, LOST, WAITING, Monitor
from gcs.retask import Retasker, RetaskError, in_parallel
from gcs.segments import Segments, segment_capacity, upload_route
from missions.build import vehicle_mission
from missions.check import checked
from missions.segments import RouteMissions, fewer_waypoints
from planner.fleet import prove_separated, stop_time
from planner.plan import PLAN_FILE, Plan

from . import report as reporting
from .batteries import Batteries
from .departures import Departures, flight_bases
from .holds import Holds
from .left_out import LeftOut
from .options import (
    LOOP_S,
    PLAN_FROM_HERE,
    TLOG_PATTERN,
    FlightError,
    FlyOptions,
    launch_tolerance,
)
from .preflight import Preflight, start_name
from .state import FlightState

#: after a timeout brought the vehicles home, wait at least this long (wall s) for them
HOME_WAIT_S = 60.0


class _TimedOut(Exception):
    """--timeout reached while vehicles were still flying."""


def assign_vehicles(plan: Plan, sysids: list, assign: dict) -> dict:
    """{sysid: VehicleRoute}: by ``assign`` (sysid -> vehicle id), else in order."""
    routes = {v.id: v for v in plan.vehicles}
    if assign:
        unknown = [i for i in assign.values() if i not in routes]
        if unknown:
            raise InputError("--assign", f"the plan has no vehicle {unknown[0]} "
                                         f"(vehicles {sorted(routes)})")
        missing = [s for s in assign if s not in sysids]
        if missing:
            raise InputError("--assign", f"no vehicle with system id {missing[0]} answered "
                                         f"(found {sysids})")
        return {s: routes[i] for s, i in assign.items()}
    if len(sysids) < len(plan.vehicles):
        raise InputError("--connect", f"the plan has {len(plan.vehicles)} vehicles but only "
                                      f"{len(sysids)} answered ({sysids})")
    return {s: v for s, v in zip(sorted(sysids), plan.vehicles)}


class Flight:
    """One flight of a plan; `run` does everything, the stages are there for tests."""

    def __init__(self, plan_dir, urls, options: FlyOptions, log=None, ctx=None):
        """``ctx``: the plan's `PlanningContext` when it is in memory (`gcs demo`);
        otherwise it is loaded from the plan folder."""
        plan = Plan.load(Path(plan_dir))
        self.urls = list(urls)
        self.options = options
        self.output = Path(options.output)
        self.log = log or (lambda text: None)
        monitor = Monitor(options.lost_after_s, on_event=self._on_event,
                          track_tolerance_m=plan.params.get("track_tolerance_m"))
        self.state = FlightState(Path(plan_dir), plan, options, monitor, FleetClock(monitor),
                                 self.log, ctx)
        self.departures = Departures(self.state)
        self.batteries = Batteries(self.state, self.departures.waiting_s)
        self.departures.on_liftoff.append(self.batteries.lifted)
        self.departures.awaits_operator = self.batteries.swap_awaited
        self.segments = Segments(monitor, options.protocol, options.max_items)
        self.holds = Holds(self.state, self.segments, self.batteries.short,
                           self.departures.waiting_s)
        self.preflight = Preflight(self.state, self.plan_from_where_they_stand)
        self.left_out = LeftOut(self.state, self.context)
        monitor.awaited = self.state.awaited
        monitor.swapping = self.batteries.swapping
        monitor.swap_silence_s = options.swap_silence_s
        self.guard = None
        self.min_separation_m = None  # the plan's, proven again in `prepare`
        self.start_unix = time.time()
        self.busy0_s = busy_total_s()   # the ground station's busy spells before it
        self.link = None
        self.retasks = []
        self._unlocked = {}           # vehicles held for each other -> times found so
        self.missions = None      # (route id, firmware) -> CheckedMission, once prepared
        self.timed_out = False
        self.stopped = None       # why monitoring ended early ("interrupted", "timed out")
        self.error = None         # what stopped the flight (FlightError)

    # what the parts share, as the flight's own
    monitor = property(lambda self: self.state.monitor)
    clock = property(lambda self: self.state.clock)
    plan = property(lambda self: self.state.plan)
    plan_dir = property(lambda self: self.state.plan_dir)
    ctx = property(lambda self: self.state.ctx)
    surface = property(lambda self: self.state.ctx.surface)

    # -- stages -------------------------------------------------------------------------
    def prepare(self) -> None:
        """Read the plan and prove every route's mission, for each autopilot, before
        any connection: InputError naming the plan and vehicle if one fails."""
        if self.missions is not None:
            return
        ctx = self.state.load_context()
        clearance = self.plan.params.get("clearance_m")
        missions = {}
        for route in self.plan.vehicles:
            if not route.waypoints:
                continue
            for firmware in NAMES:      # every sortie's, the first kept for the upload
                for j, part in reversed(list(enumerate(route.sortie_routes(), start=1))):
                    mission = vehicle_mission(part, firmware, self.state.mission_options)
                    missions[route.id, firmware] = checked(
                        mission, ctx.surface, clearance,
                        name=f"{self.plan_dir / PLAN_FILE}: vehicle {route.id}"
                             + (f" sortie {j}" if route.sorties else ""))
        self.missions = missions
        terrain = ctx.surface.terrain
        # the fleet keeps apart as planned: proven again from what the missions fly
        self.min_separation_m = prove_separated(self.plan, terrain,
                                                ctx.scenario.travel_params(),
                                                source=str(self.plan_dir / PLAN_FILE))

        def ground(lat, lon):
            return terrain.ground_at(*terrain.from_lonlat(lon, lat))

        self.monitor.ground = ground

    def run(self, status=None, on_interrupt=None, on_timeout=None) -> dict:
        """Fly the plan to the end; returns the report (also written to flight.json).

        Ctrl-C while monitoring calls ``on_interrupt()``, and the end of
        ``timeout_s`` with vehicles still flying calls ``on_timeout()`` (default:
        "home"): "home" re-tasks every vehicle in the air home along hidden paths
        (never plain RTL) and keeps monitoring; anything else leaves them on their
        missions and stops. A FlightError is re-raised after the report is written."""
        self.prepare()
        self.output.mkdir(parents=True, exist_ok=True)
        threading.Thread(target=self.state.prepare_context, daemon=True,
                         name="replan-context").start()
        self.monitor.watch_losses()
        try:
            self.connect()
            self.preflight.locate()
            self.preflight.check_failsafes()
            self.preflight.check_rates()
            self.upload()
            self.start()
            self._watch_and_answer(status, on_interrupt, on_timeout or (lambda: "home"))
        except FlightError as exc:
            self.error, failure = str(exc), exc
            self.monitor.event(None, f"failed: {exc}")
            self._home_after_failure()
        finally:
            self.monitor.close()
            if self.link is not None:
                self.link.close()
        document = self.report()
        self.write(document)
        if self.error is not None:
            raise failure               # its kind kept: a refused failsafe exits 2
        return document

    def check_rates(self) -> None:
        self.preflight.check_rates()

    def _watch_and_answer(self, status, on_interrupt, on_timeout) -> None:
        """Monitor; on Ctrl-C or the timeout ask what to do (once each time)."""
        try:
            self.watch(status, self.options.timeout_s)
            return
        except KeyboardInterrupt:
            why = "interrupted"
            choice = on_interrupt() if on_interrupt is not None else "leave"
        except _TimedOut:
            why = f"timed out after {self.options.timeout_s:g} s"
            self.timed_out = True
            choice = on_timeout()
        self.monitor.event(None, f"{why}: {choice}")
        self.stopped = why
        if choice != "home":
            return
        if self._bring_home(status, bounded=self.options.timeout_s is not None):
            self.stopped = None

    def _bring_home(self, status, bounded: bool) -> bool:
        """Every vehicle in the air home along hidden paths (never RTL), watched until
        down; ``bounded``: for no longer than the flights home take, twice over (at
        least `HOME_WAIT_S`). False when stopped before they all landed."""
        self.retask(home=True)
        bound = max(self.options.timeout_s or 0.0, HOME_WAIT_S, self._home_wall_s()) \
            if bounded else None
        try:
            self.watch(status, bound)
            return True
        except (KeyboardInterrupt, _TimedOut):
            self.monitor.event(None, "stopped while bringing the vehicles home")
            return False

    def _home_after_failure(self) -> None:
        """The flight failed (a start refused, an upload that cannot be done) with
        vehicles in the air: they are not left on their missions with nobody
        watching (no guard, no re-plan on a loss), but brought home by hidden paths
        (never RTL) and watched until down, as on a timeout."""
        m = self.monitor
        up = [s for s, v in sorted(m.vehicles.items()) if v.airborne and not v.finished]
        if not up:
            return
        m.event(None, "the flight failed: the vehicles in the air are brought home by "
                      "hidden paths", vehicles=up)
        self.departures.clear()
        for parts in self.state.later.values():
            parts.clear()
        try:
            self._bring_home(None, bounded=True)     # nobody is asked: never forever
        except FlightError as exc:
            m.event(None, f"could not bring them all home: {exc}")

    def _home_wall_s(self) -> float:
        """Wall seconds the flights home take, twice over: the re-plan's mission time
        at the fleet clock's rate (a simulator on a busy machine runs slower)."""
        planned = self.retasks[-1].planned if self.retasks else {}
        return 2.0 * float(planned.get("mission_time_s") or 0.0) / max(self.clock.rate(), 1e-3)

    def context(self):
        return self.state.context()

    def connect(self) -> None:
        o = self.options
        expect = sorted(o.assign) if o.assign else len(self.plan.vehicles)
        tlog = str(self.output / TLOG_PATTERN) if o.tlog else None
        try:
            self.link = GroundLink.open(self.urls, o.signing_key, expect=expect,
                                        timeout_s=o.connect_timeout_s, tlog=tlog,
                                        forward=o.forward)
        except LinkError as exc:
            raise FlightError(str(exc)) from None
        vehicles = self.link.vehicles
        for sysid, route in assign_vehicles(self.plan, list(vehicles), o.assign).items():
            link = vehicles[sysid]
            mission = self.missions.get((route.id, link.flavour))
            if mission is None:
                raise FlightError(f"vehicle {sysid}: its autopilot ({link.flavour}) is neither "
                                  f"{' nor '.join(NAMES)}: no mission for it")
            self._follow(link, route, mission)
            self.monitor.event(sysid, "connected", flavour=link.flavour, vehicle=route.id,
                               items=len(mission.items))

    def route_missions(self, route, firmware) -> RouteMissions:
        """The missions that fly ``route`` with ``firmware``, each proven by the gate
        (`checked`). The plan's waypoints are already the fewest the leg proofs allow
        (its schedule counts a stop at each): only repeated places are left out."""
        clearance = self.plan.params.get("clearance_m")
        name = f"{self.plan_dir / PLAN_FILE}: vehicle {route.id}"
        surface = self.state.ctx.surface
        return RouteMissions(route, firmware, self.state.mission_options,
                             lambda mission: checked(mission, surface, clearance, name=name),
                             fly=fewer_waypoints(route))

    def upload(self) -> None:
        m = self.monitor
        missions = {}
        for sysid, v in m.vehicles.items():
            try:
                missions[sysid] = self.route_missions(v.route, m.links[sysid].flavour)
            except InputError as exc:
                raise FlightError(str(exc)) from None

        def one(sysid):
            def learned(capacity, how):
                m.event(sysid, "mission capacity", capacity=capacity, how=how)

            mission = upload_route(m.links[sysid], missions[sysid], self.options.protocol,
                                   on_capacity=learned, limit=self.options.max_items)
            m.set_mission(sysid, mission)
            self.segments.fly(sysid, missions[sysid])
            whole = len(missions[sysid])
            m.event(sysid, "mission uploaded and verified", items=len(mission),
                    **({} if mission.final else {"route_items": whole, "segment": 1}))
            if not mission.final:
                self._unheard_ends(sysid, missions[sysid])

        self.state.on_every(one, "upload", (MissionError, InputError))

    def _unheard_ends(self, sysid, missions) -> None:
        """Said before takeoff: segment ends its plan has in a radio shadow, where the
        next segment cannot be uploaded (the vehicle waits there unheard, and is
        declared lost when overdue)."""
        capacity = segment_capacity(self.monitor.links[sysid], self.options.max_items)
        ends = missions.unheard_ends(capacity)
        if ends:
            self.monitor.event(
                sysid, f"{len(ends)} of its segments of {capacity} items end in predicted "
                       "radio shadows, where the next cannot be uploaded: it will wait there "
                       "unheard, and be declared lost when overdue (a vehicle holding more "
                       "items, or an --antenna in sight of those legs, avoids it)",
                unheard_ends=ends)

    def start(self) -> None:
        """The fleet clock starts; every vehicle takes off at its planned time
        (`Departures`): those due now here, the others from `watch`."""
        m = self.monitor
        self.guard = SeparationGuard(
            m, self.state.separation_m, {s: v.route.priority for s, v in m.vehicles.items()},
            self.clock, self.holds, travel=self.state.ctx.scenario.travel_params(),
            stop_s=stop_time(self.plan.params), bases=flight_bases(self.plan))
        self.departures.in_way = self.guard.in_way_of_takeoff
        # every vehicle ready to arm first: then each start takes about as long, and the
        # takeoffs keep the plan's spacing
        self.state.on_every(lambda s: commands.wait_ready(m.links[s], self.options.ready_timeout_s),
                            "start", commands.CommandError)
        self.departures.launch_all()
        self.departures.due()

    def plan_from_where_they_stand(self, off) -> None:
        """The operator's choice for vehicles off their launch points: the plan's
        scenario planned again with each such vehicle's base where it stands (the
        others' where planned), written to ``PLAN_FROM_HERE`` in the output folder and
        flown instead, every mission and the separation proven again as any plan's.
        A vehicle standing where no hidden takeoff is possible is refused by name."""
        from gcs.plan_folder import write_plan_folder
        from planner.replan import BaseRefused, plan_from_bases

        from .preflight import start_of

        m = self.monitor
        here = {sysid: (lat, lon) for sysid, _, _, lat, lon in off}
        for sysid, route, d, lat, lon in off:
            m.event(sysid, f"stands {d:.1f} m from {start_name(route)} of route "
                           f"{route.id}: planning again from where it stands")
        by_route = {v.route.id: here.get(sysid) or (start_of(v.route).lat, start_of(v.route).lon)
                    for sysid, v in m.vehicles.items()}
        launch = [by_route.get(v.id) or (start_of(v).lat, start_of(v).lon)
                  for v in self.plan.vehicles]
        sysid_of = {v.route.id: sysid for sysid, v in m.vehicles.items()}
        moved = [i for i, v in enumerate(self.plan.vehicles) if sysid_of.get(v.id) in here]
        try:
            ctx, outcome = plan_from_bases(self.context(), launch, moved, log=self.log)
            folder = self.output / PLAN_FROM_HERE
            write_plan_folder(folder, ctx, outcome)
        except BaseRefused as exc:
            sysid = sysid_of[self.plan.vehicles[exc.index].id]
            raise FlightError(f"cannot plan from where the vehicles stand: vehicle "
                              f"{sysid}: {exc.problem}") from None
        except InputError as exc:
            raise FlightError(f"cannot plan from where the vehicles stand: {exc}") from None
        self._fly_instead(folder, ctx)
        m.event(None, f"flying the plan made from where they stand ({folder}): coverage "
                      f"time {outcome.plan.metrics['coverage_time_s'] / 60:.1f} min")

    def _fly_instead(self, folder, ctx) -> None:
        """Fly the plan in ``folder`` (made in memory as ``ctx``) with the vehicles
        connected now, each on the route of the same number, proven as `prepare` does."""
        self.state.plan_dir, self.state.plan = Path(folder), Plan.load(folder)
        self.state.ctx, self.missions = ctx, None
        self.prepare()
        routes = {v.id: v for v in self.plan.vehicles}
        for sysid, v in list(self.monitor.vehicles.items()):
            link = self.monitor.links[sysid]
            self._follow(link, routes[v.route.id], self.missions[v.route.id, link.flavour])

    def _follow(self, link, route, mission) -> None:
        """The monitor follows ``link`` flying ``route``'s first sortie as ``mission``;
        its later sorties wait their turn (`_next_sorties`)."""
        first, *later = route.sortie_routes()
        self.monitor.follow(link, route.id, first, mission)
        self.state.later[link.sysid] = [(0.0, part) for part in later]

    # -- the loop -----------------------------------------------------------------------
    def watch(self, status=None, timeout_s=None) -> None:
        """Monitor until every vehicle has landed or is lost; re-task on each loss.
        _TimedOut after ``timeout_s`` wall seconds with vehicles still flying."""
        m = self.monitor
        end = None if timeout_s is None else time.monotonic() + timeout_s
        while True:
            # every loss found so far, here or while waiting on vehicles (uploads,
            # segment switches): the last one flying may leave the others down
            m.check_losses()
            lost, back = m.take_losses(), m.take_rejoined()
            if lost or back or self.left_out.short():
                self.retask(home=self.left_out.home, rejoined=back)
            self._next_sorties()
            if self.batteries.watch():
                self.retask()
            # a loss found since (on the ground as its next sortie uploads, or by the
            # loss thread) is re-tasked for first: the survivors, down already, fly its
            # work (the flight once ended with it unflown)
            if m.all_finished() and not self.departures and not m.awaited() and \
                    not m.losses_waiting():
                break
            self.departures.due()
            if self.guard is not None:
                self.guard.step()
                self._unlock(self.guard.deadlocked)
            due = self.segments.due()
            if due:
                self.next_segments(due)
            if status is not None:
                status(m.status_rows())
            if end is not None and time.monotonic() > end and not m.all_finished():
                raise _TimedOut()
            time.sleep(LOOP_S)
        if status is not None:
            status(m.status_rows())

    def _unlock(self, held) -> None:
        """Vehicles the guard holds for each other, none able to go first, are
        re-planned from where they stand (the re-plan's fleet clock orders them).
        The same ones held so after that re-plan are said once and left held (a
        re-plan each loop would only hold them again): the battery watch brings
        them home, or the operator moves them."""
        if not held:
            return
        key = frozenset(held)
        seen = self._unlocked.get(key, 0)
        self._unlocked[key] = seen + 1
        if seen == 0:
            self.monitor.event(None, "separation guard: vehicles held for each other, none "
                                     "may go first: re-planned from where they stand",
                               held=held)
            self.retask()
        elif seen == 1:
            self.monitor.event(None, "separation guard: vehicles held for each other again "
                                     "after a re-plan: left held for the battery watch or "
                                     "the operator", held=held)

    def _next_sorties(self) -> None:
        """A vehicle down at its base after a sortie flies its next one at its planned
        time, once its battery is swapped (`Batteries.ready`); one that landed
        elsewhere flies no more sorties."""
        m = self.monitor
        for sysid, parts in self.state.later.items():
            v = m.vehicles[sysid]
            if not parts or v.state != LANDED or sysid in self.departures:
                continue
            offset, route = parts[0]
            state = m.links[sysid].state
            if state.lat is None or distance_m(route.launch.lat, route.launch.lon, state.lat,
                                               state.lon) > launch_tolerance(self.plan):
                parts.clear()
                m.event(sysid, "landed away from its base: its later sorties are not flown")
                continue
            if not self.batteries.ready(sysid, route, state.battery_pct):
                continue
            uploaded = {}

            def upload(s, route=route):
                missions = self.route_missions(route, m.links[s].flavour)
                uploaded[s] = missions, upload_route(m.links[s], missions, self.options.protocol,
                                                     limit=self.options.max_items)
            # the sortie stays awaited while it uploads: a vehicle falling silent on
            # the ground then is lost (and its work re-planned), not a failed flight
            with busy():
                if self.state.lost_or_failed(upload, [sysid], f"vehicle {sysid}'s next "
                                             "sortie upload", (InputError, MissionError)):
                    continue
            parts.pop(0)
            self.batteries.swapped.discard(sysid)
            missions, mission = uploaded[sysid]
            m.new_mission(sysid, route, mission)
            self.segments.fly(sysid, missions)
            m.relaunch(sysid)
            self.state.offset[sysid] = offset
            self.departures.launch(sysid, offset + route.takeoff_s, route)
            m.event(sysid, f"sortie {route.waypoints[0].sortie} uploaded and verified",
                    items=len(mission), takeoff_s=round(offset + route.takeoff_s, 1))

    def confirm_swap(self, sysid: int, where: str = "") -> bool:
        """The operator says vehicle ``sysid``'s battery is swapped (`Batteries`)."""
        return self.batteries.confirm_swap(sysid, where)

    def swap_awaited(self, sysid: int) -> bool:
        """Down between two sorties, waiting for the operator's word on its battery."""
        return self.batteries.swap_awaited(sysid)

    def next_segments(self, sysids) -> None:
        """Send ``sysids`` their next segments; a loss meanwhile re-tasks the survivors
        (`watch` takes it next)."""
        m = self.monitor
        try:
            with busy():
                lost = self.segments.switch(sysids, lambda fn, s: in_parallel(fn, s, m))
        except Exception as exc:       # a vehicle still heard from refused or failed
            raise FlightError(f"next segment failed: {exc}") from None
        if lost:
            m.event(None, "lost during a segment upload", lost=lost)

    def retask(self, home: bool = False, rejoined=()) -> None:
        """Re-plan the fleet from where it stands (`gcs.retask`): for the losses so
        far, for ``rejoined`` (taken back after a loss), or ``home``."""
        m = self.monitor
        try:
            ctx = self.context()
        except InputError as exc:
            raise FlightError(f"cannot re-plan: {exc}") from None
        m.event(None, "re-planning", survivors=m.survivors())
        if self.guard is not None:
            self.guard.forget()
        self.departures.call_off()          # the re-plan decides who goes up
        retasker = Retasker(ctx, m, self.state.mission_options, self.options.protocol,
                            segments=self.segments, depart=self.departures.depart,
                            spent=self.state.spent, pace=self.batteries.late)
        try:
            record = retasker.retask(home, rejoined)
        except RetaskError as exc:
            raise FlightError(str(exc)) from None
        # the re-plan covers what the later sorties would have: its own replace them
        now = self.clock.now() or 0.0
        self.state.later = {s: [(now, part) for part in parts]
                            for s, parts in retasker.later.items() if s in record.survivors}
        self.state.offset.update({s: now for s in record.survivors})
        if self.guard is not None:
            self.guard.priority.update(record.priority)
        for sysid, v in m.vehicles.items():     # never took off, and nothing to go up for
            if v.state == WAITING and sysid not in self.departures:
                m.set_state(sysid, LANDED)
                m.event(sysid, "stays on the ground: the re-plan has no task for it")
        self.retasks.append(record)
        self.left_out.after(record, home)

    # -- results ------------------------------------------------------------------------
    def report(self) -> dict:
        return reporting.report(self)

    def write(self, document: dict) -> None:
        reporting.write(self, document)

    def _on_event(self, entry) -> None:
        who = f"vehicle {entry['sysid']}: " if entry.get("sysid") is not None else ""
        extra = {k: v for k, v in entry.items() if k not in ("t_s", "sysid", "event")}
        tail = " " + " ".join(f"{k}={v}" for k, v in extra.items()) if extra else ""
        self.log(f"[{entry['t_s']:8.1f} s] {who}{entry['event']}{tail}")


def fly(plan_dir, urls, options: FlyOptions = None, log=None, status=None,
        on_interrupt=None, on_timeout=None, ctx=None) -> dict:
    """Fly ``plan_dir`` on the vehicles at ``urls``; returns the flight report.
    ``ctx``: the plan's context when it is in memory (else read from the folder)."""
    return Flight(plan_dir, urls, options or FlyOptions(), log, ctx).run(status, on_interrupt,
                                                                          on_timeout)


__all__ = ["Flight", "FlightError", "FlyOptions", "LANDED", "LOST", "assign_vehicles", "fly"]
