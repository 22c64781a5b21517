"""Re-tasking the survivors after a loss: hold, re-plan, upload in flight, resume.

Sequence per loss (issue 5): every survivor still in the air is held where it
is (its firmware's hold mode: ArduPilot GUIDED, PX4 AUTO.LOITER), because
ArduPilot applies an upload item by item and would otherwise fly a half-written
mission; the planner (`planner.replan`) re-plans from the held positions and the
survivors' snapshots so far; each new mission is checked (hidden, clear: a
`missions.check.CheckedMission`, the only thing the upload takes) and uploaded
with read-back; then the current item is set to the first new item and the
vehicle goes back to AUTO. When the survivors' snapshots so far leave coverage
short, landed survivors at their launch points join the re-plan, and those it
gives something to see are started again (upload, start sequence, fly).
Setting the current item is not optional: ArduPilot resumes at the old index
after an upload.

A loss during any of this (another vehicle silent, an upload failing because
its vehicle is gone) restarts the re-plan with the remaining survivors. A new
route longer than its vehicle holds goes up as its first segment, the rest in
flight (`gcs.segments`).
"""

import threading
import time
from dataclasses import dataclass, field

import numpy as np

from common.errors import InputError
from gcs import commands
from gcs.busy import busy
from gcs.monitor import (
    FLYING,
    HOLDING,
    LANDED,
    LOST,
    MIN_LAUNCH_TOLERANCE_M,
    STRANDED,
    WAITING,
    distance_m,
)
from gcs.segments import upload_route
from missions.build import MissionOptions
from missions.segments import RouteMissions, fewer_waypoints
from planner.replan import (
    Survivor,
    coverable_targets,
    coverage_summary,
    place_counts,
    replan,
    requirement,
    survivor_start,
)

MAX_ATTEMPTS = 4


class RetaskError(Exception):
    """Re-tasking could not be done (no survivor, or a survivor refused)."""


@dataclass
class Retask:
    """One re-plan, as written to flight.json."""

    t_s: float
    lost: list  # system ids lost so far when it was made
    survivors: list = field(default_factory=list)  # system ids re-tasked
    left_out: list = field(default_factory=list)  # out of contact as planned: flying their plan
    rejoined: list = field(default_factory=list)  # heard again after a loss: re-planned with them
    stranded: list = field(default_factory=list)  # held: no hidden leg joins them
    relaunched: list = field(default_factory=list)  # of them, landed ones sent up again
    attempts: int = 0
    planning_s: float = 0.0
    upload_s: float = 0.0
    done_t_s: float | None = None
    required_uavs: int = 0
    seen_before: dict = field(default_factory=dict)  # coverage by survivors' snapshots so far
    original: dict = field(default_factory=dict)  # the rest of the original plan, evaluated
    planned: dict = field(default_factory=dict)  # the re-plan's own metrics
    routes: dict = field(default_factory=dict)  # sysid -> [[lon, lat, alt AMSL], ...]
    starts: dict = field(default_factory=dict)  # sysid -> held position [lon, lat, alt]
    departs: dict = field(default_factory=dict)  # sysid -> s after the re-plan it flies on
    priority: dict = field(default_factory=dict)  # sysid -> right of way (1 first)


def geo_to_xyz(ctx, lon, lat, alt) -> np.ndarray:
    x, y = ctx.terrain.from_lonlat(lon, lat)
    return np.array([float(x), float(y), float(alt)])


def points_xyz(ctx, points) -> np.ndarray:
    """(n, 3) projected x, y and altitude AMSL of points with lon, lat, alt_amsl."""
    if not points:
        return np.zeros((0, 3))
    x, y = ctx.terrain.from_lonlat(np.array([p.lon for p in points], float),
                                   np.array([p.lat for p in points], float))
    return np.stack([x, y, [p.alt_amsl for p in points]], axis=1)


def snapshot_xyz(ctx, progress) -> np.ndarray:
    """(n, 3) projected positions of the snapshots a vehicle has taken."""
    return points_xyz(ctx, progress.snapshots)


def remaining_snapshot_xyz(ctx, progress) -> np.ndarray:
    """Snapshots of the mission being flown that are not taken yet."""
    waypoints = progress.route.waypoints
    return points_xyz(ctx, [w for i, w in enumerate(waypoints)
                            if w.snapshot and i not in progress.done])


def original_outlook(ctx, monitor, sysids, n_lost: int, later=None) -> dict:
    """Would the survivors' current missions, flown to the end, meet the requirement?

    ``meets_requirement``: every coverable target seen by min(k + 1, survivors)
    survivors (what a re-plan aims at); ``tolerated``: every target seen from at
    least k + 1 places seen by k + 1 - losses (at least 1) survivors, which a
    k-tolerant plan guarantees for up to k losses without re-planning
    (``unprotected_targets``: those seen from fewer places, which it cannot). Also
    the time they still need: the latest planned time of a remaining snapshot minus
    that of the last waypoint reached. ``later``: sysid -> (n, 3) snapshot points of
    the sorties it is still to fly after this one.
    """
    snaps, left, later = [], 0.0, later or {}
    for s in sysids:
        v = monitor.vehicles[s]
        rest = remaining_snapshot_xyz(ctx, v)
        snaps.append(np.vstack([snapshot_xyz(ctx, v), rest,
                                later.get(s, np.zeros((0, 3)))]))
        times = [w.t_s for i, w in enumerate(v.route.waypoints) if w.snapshot and i not in v.done]
        now = max((v.route.waypoints[i].t_s for i in v.done), default=0.0)
        if times:
            left = max(left, max(times) - now)
    counts = place_counts(ctx, snaps)
    summary = coverage_summary(ctx, snaps, ctx.scenario.k, counts)
    summary["coverable"] = coverable_targets(ctx)
    summary["meets_requirement"] = summary["k_covered"] >= summary["coverable"]
    # a target seen from fewer than k + 1 places has one sighting per place: one loss
    # can take its only one, which no plan could prevent without two vehicles flying
    # one place (a shared fate)
    places = np.diff(ctx.visibility.target_indptr)
    protected = places >= ctx.scenario.k + 1
    kept = counts >= max(1, ctx.scenario.k + 1 - n_lost)
    summary["tolerated"] = bool(kept[protected].all())
    summary["unprotected_targets"] = int(((places > 0) & ~protected).sum())
    summary["remaining_time_s"] = left
    return summary


def in_parallel(fn, sysids, monitor=None) -> dict:
    """Run fn(sysid) for each in its own thread; {sysid: exception or None}.

    With a ``monitor``, losses are checked while waiting, and a vehicle found
    lost is not waited for (its commands would only time out)."""
    errors = {}

    def run(s):
        try:
            fn(s)
            errors[s] = None
        except Exception as exc:  # reported per vehicle by the caller
            errors[s] = exc

    threads = {s: threading.Thread(target=run, args=(s,), daemon=True) for s in sysids}
    for t in threads.values():
        t.start()
    while True:
        waiting = [s for s, t in threads.items() if t.is_alive()]
        if monitor is not None:
            monitor.check_losses()
            waiting = [s for s in waiting if monitor.vehicles[s].state != LOST]
        if not waiting:
            return errors
        threads[waiting[0]].join(timeout=0.1)


class Retasker:
    """Re-plans and re-uploads the survivors of a flight (see module doc)."""

    def __init__(self, ctx, monitor, mission_options: MissionOptions = MissionOptions(),
                 protocol=None, segments=None, depart=None, spent=(), pace=None):
        """``segments``: the flight's `gcs.segments.Segments`, told what each re-tasked
        vehicle flies from now on; ``depart(sysid, after_s, kind, route)``: the flight
        sends each on its way at the re-plan's time (the fleet stays separated on it;
        None: all at once, now); ``spent``: vehicles whose battery counts as empty
        (the battery watch's: each flies home first)."""
        self.ctx = ctx
        self.segments = segments
        self.depart = depart
        self.monitor = monitor
        self.mission_options = mission_options
        self.protocol = protocol or {}  # timeout_s / retries of the mission protocol
        self.later = {}  # sysid -> the re-plan's later sorties of its route (`Flight`)
        self.spent = set(spent)
        self.pace = dict(pace or {})   # sysid -> times slower than planned (the battery watch's)
        self._retries = self.protocol.get("retries", commands.RETRIES)  # of each command
        self.home = False

    def flying(self) -> list:
        """Vehicles to re-task: not lost, not landed, not still waiting for their
        takeoff, not disarmed after flying (touched down at the end of a mission:
        it stays down unless re-launched), and heard: one out of contact as its
        plan predicts cannot be commanded, and flies its plan on (`Monitor.planned_at`).
        Nor one flying its autopilot's failsafe return (a link loss while it was held,
        its battery), in a mode gcs did not command (PX4's Hold is also ours): a hold
        would undo the way home the firmware chose."""
        m = self.monitor
        return [s for s, v in sorted(m.vehicles.items())
                if v.state not in (LOST, LANDED, STRANDED, WAITING)
                and not (v.airborne and not m.links[s].state.armed)
                and m.planned_at(s) is None
                and not (m.vehicles[s].uncommanded and m.in_failsafe(s))]

    def landed_at_launch(self) -> list:
        """Landed survivors sitting at their base (`_base`), still heard from: they
        can go up again."""
        m = self.monitor
        out = []
        for s, v in sorted(m.vehicles.items()):
            state, launch = m.links[s].state, _base(v)
            if v.state not in (LANDED, WAITING) or launch is None or state.lat is None:
                continue
            # within the room its takeoff column is proven with, as before the first start
            if distance_m(launch.lat, launch.lon, state.lat, state.lon) > \
                    max(self.ctx.scenario.track_tolerance_m, MIN_LAUNCH_TOLERANCE_M) \
                    or m.silent(s):
                continue
            out.append(s)
        return out

    def _relaunchable(self, flyers) -> list:
        """Landed survivors to send up again: when the snapshots the survivors have
        taken leave a coverable target seen by fewer than min(k + 1, survivors) of
        them, and the hidden volume takes them from their launch point."""
        landed = [s for s in self.landed_at_launch() if s not in self.spent]
        if not landed:
            return []
        ctx, m = self.ctx, self.monitor
        everyone = flyers + landed
        shots = [snapshot_xyz(ctx, m.vehicles[s]) for s in everyone]
        if coverage_summary(ctx, shots, ctx.scenario.k)["k_covered"] >= coverable_targets(ctx):
            return []
        out = []
        for s in landed:
            try:
                survivor_start(ctx, self._survivor(s, landed=True)[0])
            except InputError:
                continue                 # no hidden way up from there
            out.append(s)
        return out

    def retask(self, home: bool = False, rejoined=()) -> Retask:
        """Re-task every survivor still in the air, and the landed ones a loss needs
        up again (never for ``home``); returns the record.

        ``home``: no more coverage work, each flies home along a hidden path;
        ``rejoined``: vehicles taken back after a loss (`Monitor.take_rejoined`)."""
        self.home = home
        m = self.monitor
        lost = [s for s, v in sorted(m.vehicles.items()) if v.state == LOST]
        record = Retask(t_s=round(m.now(), 3), lost=lost, rejoined=sorted(rejoined))
        for attempt in range(1, MAX_ATTEMPTS + 1):
            record.attempts = attempt
            # nothing of an attempt cut short by a loss stands
            record.survivors, record.relaunched, self.later = [], [], {}
            m.take_losses()  # this attempt re-tasks for every loss so far, and takes
            record.rejoined = sorted(set(record.rejoined) | set(m.take_rejoined()))  # back
            sysids = self.flying()
            record.left_out = [s for s in sorted(m.vehicles) if m.planned_at(s) is not None]
            for s in record.left_out:
                # re-planning it once heard again ping-ponged: each re-plan sent another
                # into a shadow, and the fleet was re-planned until its batteries ran out
                m.event(s, "out of contact as planned: not re-tasked, it flies its plan on "
                           "(the others' re-plan does not count what it will still see)")
            landed = [] if home else self._relaunchable(sysids)
            if not sysids and not landed:
                m.event(None, "re-plan skipped: no survivor in the air or able to go up")
                return record
            try:
                self._attempt(record, sysids, landed)
                record.done_t_s = round(m.now(), 3)
                if not record.survivors:
                    m.event(None, "re-plan skipped: every survivor is stranded"
                            if record.stranded else "re-plan skipped: it gives no survivor "
                            "anything left to see")
                    return record
                m.event(None, "re-tasked", survivors=record.survivors, attempt=attempt,
                        **({"relaunched": record.relaunched} if record.relaunched else {}))
                return record
            except _LostDuring as exc:
                m.event(None, f"{exc.what} during re-tasking: starting again",
                        **{exc.what: exc.sysids})
        raise RetaskError(f"re-tasking failed {MAX_ATTEMPTS} times in a row")

    # -- one attempt --------------------------------------------------------------------
    def _survivor(self, sysid, landed=False) -> tuple:
        """(Survivor, [lon, lat, alt]) of a vehicle: where it is held, or for a landed
        one its base (it climbs straight up from there, as at takeoff); the base
        it comes home to (`_base`)."""
        ctx, v = self.ctx, self.monitor.vehicles[sysid]
        launch = _base(v)
        state = self.monitor.links[sysid].state
        position = [launch.lon, launch.lat, launch.alt_amsl] if landed else \
            [state.lon, state.lat, state.alt_amsl]
        legs = None if landed else points_xyz(ctx, v.route.waypoints)  # it flies now
        return (Survivor(v.vehicle_id, geo_to_xyz(ctx, *position),
                         geo_to_xyz(ctx, launch.lon, launch.lat, launch.alt_amsl),
                         self._flown_s(sysid), sysid in self.spent, legs), position)

    def _flown_s(self, sysid) -> float:
        """What a survivor's battery has flown, from the share left it reports
        (SYS_STATUS): a re-plan with an endurance flies it no further than that allows.
        One that makes its way ``pace`` times slower than planned (a headwind) has
        that much less of the planned flight left in what remains."""
        s = self.ctx.scenario
        if s.endurance_min is None:
            return 0.0
        pct = self.monitor.links[sysid].state.battery_pct
        if pct is None:
            self.monitor.event(sysid, "battery not reported: re-planned as if full")
            return 0.0
        full = 60.0 * s.endurance_min
        return full - full * min(pct, 100) / 100.0 / self.pace.get(sysid, 1.0)

    def _attempt(self, record, sysids, landed=()) -> None:
        m = self.monitor
        landed = list(landed)
        if sysids:
            self._step(sysids, self._hold)
            m.wait_settled(sysids, vertical=False)  # a re-plan starts where they are
            for s in sysids:        # what one flew unheard (a shadow, a false loss) counts
                m.catch_up(s)
            self._still_flying(sysids)      # one touched down before it was held
            sysids = self._strand_unjoined(record, sysids)
            if not sysids and not landed:
                return
        with busy():                        # they hover at real time meanwhile
            self._plan_and_send(record, sysids, landed)

    def _plan_and_send(self, record, sysids, landed) -> None:
        """Re-plan the held ``sysids`` and the ``landed`` survivors from where they
        stand, upload their routes and set them going."""
        m, ctx = self.monitor, self.ctx
        t0 = time.perf_counter()
        everyone = list(sysids) + landed
        survivors, positions = [], {}
        for s in everyone:
            survivor, positions[s] = self._survivor(s, landed=s in landed)
            survivors.append(survivor)
        shots = [snapshot_xyz(ctx, m.vehicles[s]) for s in everyone]
        record.survivors, record.starts = sorted(everyone), positions
        record.required_uavs = int(requirement(ctx, len(everyone))[1][0])
        record.seen_before = coverage_summary(ctx, shots, ctx.scenario.k)  # by place
        record.original = original_outlook(ctx, m, everyone, len(record.lost))
        try:
            required = np.zeros(ctx.visibility.n_targets, np.int32) if self.home else None
            outcome = replan(ctx, survivors, required=required, snapshots=shots)
        except InputError as exc:
            raise RetaskError(f"re-plan failed: {exc}") from None
        record.planning_s = round(time.perf_counter() - t0, 3)
        record.planned = dict(outcome.plan.metrics)
        over = (record.planned.get("battery") or {}).get("over_battery")
        if over:
            m.event(None, f"re-plan: a sortie takes {over:.2f} times the usable battery "
                          "(the survivors' batteries are partly flown): the battery watch "
                          "guards it")
        # a route of several sorties flies its first now, the others after landing
        parts = {s: r.sortie_routes() for s, r in zip(everyone, outcome.plan.vehicles)}
        routes = {s: p[0] for s, p in parts.items()}
        self.later = {s: p[1:] for s, p in parts.items()}
        # a landed vehicle goes up now only if the re-plan gives its first sortie
        # something to see; one whose battery is spent (just landed, not swapped yet)
        # gets its work in later sorties, flown as any vehicle's next sortie: once
        # its battery is fresh (`Flight._next_sorties`)
        up = [s for s in landed if _sees(routes[s])]
        for s in landed:
            self.later[s] = [p for p in self.later[s] if _sees(p)]
        swapping = [s for s in landed if s not in up and self.later[s]]
        tasked = list(sysids) + up
        record.survivors, record.relaunched = sorted(tasked + swapping), up
        try:
            missions = {s: self._missions(s, routes[s]) for s in tasked}
        except InputError as exc:       # nothing is sent: the vehicles stay held
            raise RetaskError(f"re-planned mission refused by the check: {exc}") from None
        record.routes = {s: [[w.lon, w.lat, w.alt_amsl] for w in routes[s].waypoints]
                         for s in tasked}
        # held at the bottom of its column, one touches down as it is planned for
        # (real ArduPilot SITL, 1.1 s after its hold): its route from the air would
        # be "resumed" on the ground, and its work never flown
        self._still_flying(sysids)
        t1 = time.perf_counter()
        uploaded = {}

        def upload(s):
            def learned(capacity, how):
                m.event(s, "mission capacity", capacity=capacity, how=how)

            uploaded[s] = upload_route(m.links[s], missions[s], self.protocol, learned,
                                       limit=getattr(self.segments, "limit", None))

        self._step(tasked, upload)
        record.upload_s = round(time.perf_counter() - t1, 3)
        for s in tasked:
            # held until its time on the re-plan's clock (from now), or sent on at once
            m.new_mission(s, routes[s], uploaded[s],
                          0.0 if self.depart is not None else routes[s].takeoff_s)
            if self.segments is not None:
                self.segments.fly(s, missions[s])
        record.departs = {s: routes[s].takeoff_s for s in tasked}
        record.priority = {s: routes[s].priority for s in tasked}
        for s in up:
            m.relaunch(s)
        if self.depart is not None:     # each at its time on the re-plan's clock
            for s in tasked:
                self.depart(s, routes[s].takeoff_s, "launch" if s in up else "resume",
                            routes[s])
            return
        self._step(sysids, lambda s: self.resume(m, s, self._retries))
        self._step(up, lambda s: self._launch(s, routes[s]))
        for s in tasked:
            m.set_state(s, FLYING)

    def _missions(self, sysid, route) -> RouteMissions:
        """The new route's missions (the whole, or segments), each proven hidden and
        clear leg by leg: `CheckedMission`, the only thing the upload takes; the
        re-plan's waypoints are already the fewest its leg proofs allow."""
        from missions.check import checked

        link = self.monitor.links[sysid]
        ctx = self.ctx
        return RouteMissions(route, link.flavour, self.mission_options,
                             lambda mission: checked(mission, ctx.surface,
                                                     ctx.scenario.clearance_m),
                             fly=fewer_waypoints(route))

    def _still_flying(self, sysids) -> None:
        """_LostDuring if one of the held ``sysids`` is no longer to re-task in the
        air (touched down, lost, or gone into a predicted shadow): the attempt
        starts again, a landed one among the landed survivors."""
        flying = self.flying()
        gone = [s for s in sysids if s not in flying]
        if not gone:
            return
        m = self.monitor
        what = "lost" if any(m.vehicles[s].state == LOST for s in gone) else \
            "out of contact" if any(m.planned_at(s) is not None for s in gone) else "landed"
        raise _LostDuring(gone, what)

    def _strand_unjoined(self, record, sysids) -> list:
        """``sysids`` without the held vehicles no hidden leg joins to the hidden
        volume: no route can start there, so they stay held, left to the operator,
        and the others are re-planned (one stray vehicle does not stop the flight)."""
        m, joined = self.monitor, []
        for s in sysids:
            survivor, position = self._survivor(s)
            try:
                survivor_start(self.ctx, survivor)
                joined.append(s)
            except InputError as exc:
                m.set_state(s, STRANDED)
                m.event(s, "stranded: held where it is, the operator takes over",
                        reason=str(exc), lon_lat_alt=[round(float(v), 7) for v in position])
                record.stranded.append(s)
        return joined

    def _step(self, sysids, fn) -> None:
        """fn on every survivor at once; a failure of a vehicle found lost restarts."""
        since = self.monitor.now()
        errors = in_parallel(fn, sysids, self.monitor)
        newly = self.monitor.check_losses()
        failed = {s: e for s, e in errors.items() if e is not None}
        gone = [s for s in sysids if self.monitor.vehicles[s].state == LOST]
        if gone or newly:
            raise _LostDuring(sorted(set(gone) | set(newly)))
        # gone into a predicted radio shadow meanwhile: it flies its plan, the others
        # are re-planned without it (it may have taken the command: said by the event);
        # one back out of it just as the command's tries ran out (a shadow of 9 s, the
        # tries' 9 s) is re-planned afresh, with its new position, not a failed flight
        quiet = [s for s in failed if self.monitor.planned_at(s) is not None
                 or _silent_since(self.monitor.vehicles[s], since)]
        if quiet:
            raise _LostDuring(quiet, "out of contact")
        if failed:
            s, exc = next(iter(failed.items()))
            raise RetaskError(f"vehicle {s}: {exc}")

    def _hold(self, sysid) -> None:
        link = self.monitor.links[sysid]
        commands.set_mode(link, commands.autopilot(link).hold_mode, retries=self._retries)
        self.monitor.set_state(sysid, HOLDING)

    def _launch(self, sysid, route) -> None:
        """A landed survivor's start sequence, as at the start of the flight."""
        commands.start_mission(self.monitor.links[sysid], route.waypoints[0].alt_amsl,
                               retries=self._retries)

    @staticmethod
    def resume(monitor, sysid, retries=commands.RETRIES) -> None:
        """Current item = the first item flown (after home, where there is one), then
        the firmware's mission mode."""
        link = monitor.links[sysid]
        profile = commands.autopilot(link)
        commands.set_current(link, profile.first_item, retries=retries)
        commands.set_mode(link, profile.mission_mode, retries=retries)


def _silent_since(v, t_s) -> bool:
    """Whether vehicle record ``v`` was out of contact as planned at some time after
    ``t_s`` (a predicted silence not over by then)."""
    return any(x["to_s"] is None or x["to_s"] >= t_s for x in v.silences)


class _LostDuring(Exception):
    """Survivors ``what`` ("lost", "landed" or "out of contact") while re-tasking:
    start again."""

    def __init__(self, sysids, what="lost"):
        self.sysids, self.what = sysids, what
        super().__init__(f"{what} during re-tasking: {sysids}")


def _sees(route) -> bool:
    """Whether a route (a sortie) photographs anything."""
    return any(w.snapshot for w in route.waypoints)


def _base(v):
    """The base a vehicle stands at or comes home to: where its flight lands (its
    launch point, or another base a sortie lands at), or before its takeoff its
    launch point."""
    return v.route.launch if v.state == WAITING else v.route.landing
