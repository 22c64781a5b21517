"""The `Monitor`: one object, one lock, over the telemetry of every vehicle of a
flight. Here: following a vehicle's link, the event log, the flight state the
flight sets, the missions and the progress along them, losses and silences, the
views of the status table; its telemetry and landing parts are modules of their
own."""

import collections
import math
import threading
import time

import numpy as np

from gcs.contact import Contact
from gcs.corridor import POSITION_MARGIN_M, ProvenPath
from missions.returns import landing_gaps

from .landing import Landing
from .records import (
    FLYING,
    HOLDING,
    LANDED,
    LOST,
    SETTLE_S,
    SETTLED_MPS,
    STARTING,
    STRANDED,
    SWAP_SILENCE_S,
    WAITING,
    Snapshot,
    VehicleProgress,
)
from .telemetry import Telemetry


def _own_at(state, mono: float) -> float | None:
    """A vehicle's own clock (s since boot) at ``mono`` (time.monotonic()): its latest
    report's, carried on at its clock's rate; None unknown."""
    boot_s, boot_at = getattr(state, "boot_s", None), getattr(state, "boot_at", None)
    if boot_s is None or boot_at is None:
        return None
    return boot_s + (mono - boot_at) * getattr(state, "clock_rate", 1.0)


def mission_items(mission) -> int:
    """Items of ``mission`` (0 for None): by its len() where it has one, as a checked
    mission does, whose ``items`` are copies made on each read (the status line's
    read of them was a tenth of the flight loop's time)."""
    if mission is None:
        return 0
    return len(mission) if hasattr(mission, "__len__") else len(mission.items)


def _or_dash(value) -> str:
    return "-" if value is None else str(value)


def shown_item(state, items: int) -> int | None:
    """The item of its current mission (``items`` long) a vehicle reports flying, for
    the operator; None before it reports one: a MISSION_CURRENT of the mission before
    still on its way names an item past this one's end (a relaunched vehicle shown
    at "item 70/49")."""
    seq = getattr(state, "mission_seq", None)
    return int(seq) if seq is not None and 0 <= seq < items else None


def _speed(state, vertical: bool) -> float:
    """m/s from the last GLOBAL_POSITION_INT: ground speed, or 3-D with ``vertical``."""
    if vertical and state.velocity is not None:
        return math.hypot(*state.velocity)
    return math.inf if state.groundspeed is None else state.groundspeed


class StallClock:
    """How long this ground station itself stood still: a thread that wakes every
    `PERIOD_S` records each gap longer than that (the process starved of CPU by a
    busy machine, or held by a long computation). Silence heard while the ground
    station was not listening is no evidence that a vehicle is gone."""

    PERIOD_S = 0.05
    KEPT = 4096          # gaps remembered (the oldest are dropped)

    def __init__(self):
        self._gaps = collections.deque(maxlen=self.KEPT)    # (start, end), monotonic
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="stall-clock", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        last = time.monotonic()
        while not self._stop.wait(self.PERIOD_S):
            now = time.monotonic()
            if now - last > 2 * self.PERIOD_S:
                self._gaps.append((last + self.PERIOD_S, now))
            last = now

    def stalled(self, since: float) -> float:
        """Seconds since monotonic time ``since`` this process did not run."""
        return sum(max(0.0, end - max(start, since)) for start, end in list(self._gaps)
                   if end > since)

    def stop(self) -> None:
        self._stop.set()


class Monitor(Telemetry, Landing):
    """Telemetry of every vehicle of a flight, on one clock (seconds since `t0`)."""

    def __init__(self, lost_after_s: float = 5.0, on_event=None, ground=None,
                 track_tolerance_m=None):
        """``ground(lat, lon)``: terrain altitude (m AMSL; NaN outside) of the plan's
        DEM, to tell a vehicle that went below it; ``track_tolerance_m``: the room
        the plan's legs are proven with, to tell a vehicle off them; None: not judged."""
        self.lost_after_s = float(lost_after_s)
        self.ground = ground
        self.track_tolerance_m = track_tolerance_m
        self.stalls = StallClock()
        self.awaited = set     # () -> sysids landed with a sortie still to fly (`Flight`)
        self.swapping = set    # () -> of them, down at base, their battery swap not yet seen
        self.swap_silence_s = SWAP_SILENCE_S
        self.t0 = time.monotonic()
        self.vehicles = {}  # sysid -> VehicleProgress
        self.links = {}  # sysid -> VehicleLink
        self.events = []  # [{"t_s", "sysid", "event", ...}]
        self._lock = threading.RLock()
        self._untaken = []  # lost vehicles not yet taken by the flight (`take_losses`)
        self._rejoined = []  # vehicles taken back after a loss, not yet re-planned for
        self._unsubscribe = []
        self._on_event = on_event
        self._watching = None  # the event that stops `watch_losses`

    def now(self) -> float:
        return time.monotonic() - self.t0

    # -- setting up -----------------------------------------------------------------
    def follow(self, link, vehicle_id: int, route, mission) -> VehicleProgress:
        """Start following vehicle ``link`` flying ``route`` as ``mission`` (again, from
        the start: a vehicle on the ground given another plan)."""
        progress = VehicleProgress(link.sysid, vehicle_id, link.flavour, route, mission)
        progress.proven = ProvenPath(route)
        progress.contact = Contact(route.silences, trajectory=route.trajectory)
        with self._lock:
            known = link.sysid in self.links
            self.vehicles[link.sysid] = progress
            self.links[link.sysid] = link
        if not known:
            self._unsubscribe.append(link.subscribe(lambda msg, s=link.sysid: self._on(s, msg)))
        return progress

    def watch_losses(self, period_s: float = 0.2) -> None:
        """`check_losses` every ``period_s`` on a thread of its own until `close`: a
        loss is found on time even while the flight computes (a re-plan takes
        seconds on a busy machine) or waits on other vehicles."""
        if self._watching is not None:
            return
        self._watching = threading.Event()
        stop = self._watching

        def run():
            while not stop.wait(period_s):
                self.check_losses()
        threading.Thread(target=run, name="loss-watch", daemon=True).start()

    def close(self) -> None:
        if self._watching is not None:
            self._watching.set()
        for unsubscribe in self._unsubscribe:
            unsubscribe()
        self._unsubscribe = []
        self.stalls.stop()

    def event(self, sysid, text: str, **extra) -> dict:
        entry = {"t_s": round(self.now(), 3), "sysid": sysid, "event": text, **extra}
        with self._lock:
            self.events.append(entry)
        if self._on_event is not None:
            self._on_event(entry)
        return entry

    def set_state(self, sysid: int, state: str) -> None:
        """Move to ``state``; LANDED and LOST are final (a landed vehicle is not re-launched)."""
        with self._lock:
            v = self.vehicles[sysid]
            if v.state != state and not v.finished:
                v.state = state
                self.event(sysid, state)

    def new_mission(self, sysid: int, route, mission, fleet_s: float = 0.0) -> None:
        """The vehicle now flies ``mission`` (a re-plan, a next sortie): progress restarts
        at its item 1. One in the air is at ``fleet_s`` of ``route``'s clock now: 0
        where it is held until its ``takeoff_s`` (marked there, a silence soon after it
        flew on was read that hold's length ahead of its plan). One down at a base is
        on no clock until its liftoff marks it: marked now, its wait for its takeoff
        read as slow flight (at 150x, 2 wall s in a base column's queue halved its
        pace, and its first shadow was not matched: a loss)."""
        with self._lock:
            v = self.vehicles[sysid]
            s = self.links[sysid].state
            held = (s.lat, s.lon, s.alt_amsl) if v.airborne and s.lat is not None else None
            v.route, v.mission, v.proven = route, mission, ProvenPath(route, held)
            v.generation += 1
            v.reached, v.done = set(), set()
            v.contact.restart(route.silences, route.trajectory)
            if v.airborne and v.state != LANDED:    # airborne stays set until relaunched
                # placed, not timed: a hold until its time is not flight
                v.contact.mark(self.now(), fleet_s, self._own_clock(v), timed=False)
            self.links[sysid].state.mission_seq = None   # the old mission's; wait for news
        self._return_gaps(sysid, mission)

    def set_mission(self, sysid: int, mission) -> None:
        """The mission uploaded for the current route (the whole, or its first segment)."""
        with self._lock:
            self.vehicles[sysid].mission = mission
        self._return_gaps(sysid, mission)

    def _return_gaps(self, sysid: int, mission) -> None:
        """Where the firmware's return along ``mission`` would leave the proven legs
        (`missions.returns.landing_gaps`: PX4's Return along a mission that does not
        land at a base, or does not start above its home), said as a known risk when
        it changes: a segment or a re-task flown in the air has them all along."""
        v = self.vehicles[sysid]
        gaps = landing_gaps(mission) if getattr(mission, "firmware", None) else []
        if gaps and gaps != v.return_gaps:
            self.event(sysid, "known risk: its Return along this mission: " + "; ".join(gaps),
                       return_gaps=gaps)
        v.return_gaps = gaps

    def next_segment(self, sysid: int, mission, counted: bool = True) -> None:
        """The vehicle now flies the next segment of the same route (``counted``), or
        the rest of its segment uploaded again: item numbers start again, the
        waypoints reached and snapshots taken stay."""
        with self._lock:
            v = self.vehicles[sysid]
            v.mission = mission
            v.reached = set()
            v.segments += 1 if counted else 0
            self.links[sysid].state.mission_seq = None
        self._return_gaps(sysid, mission)

    def relaunch(self, sysid: int) -> None:
        """A landed survivor (or one still waiting for its takeoff) goes up on a
        re-plan's route."""
        with self._lock:
            v = self.vehicles[sysid]
            if v.state not in (LANDED, WAITING):
                return
            v.grounded, v.state, v.airborne = v.state, STARTING, False
            v.disarmed_at_s, v.disarmed_reports, v.lifted_at_s = None, 0, None
            v.relaunched += 1
            self.event(sysid, "re-launching")

    def call_off(self, sysid: int) -> None:
        """A start called off before the vehicle left the ground (a re-plan takes
        the fleet over): it is again what it was, down at its base; never a vehicle
        "flying" there, which a re-plan would hold and send on from the ground."""
        with self._lock:
            v = self.vehicles[sysid]
            if v.state == STARTING and not v.airborne:
                v.state = v.grounded
                self.event(sysid, f"start called off: {v.state}")

    # -- telemetry (reader threads) ---------------------------------------------------
    def _judge_route(self, v, lat, lon, alt, t) -> None:
        """Off its proven legs (beyond the track tolerance and the position's own
        error) or back on them: an event each time, the episode kept."""
        if self.track_tolerance_m is None or v.proven is None:
            return
        d = v.proven.distance_m(lat, lon, alt)
        off = v.off_route[-1] if v.off_route and v.off_route[-1][1] is None else None
        if d > self.track_tolerance_m + POSITION_MARGIN_M:
            if off is None:
                v.off_route.append([round(t, 3), None, round(d, 1)])
                self.event(v.sysid, f"{d:.0f} m off its proven route (its legs are proven "
                                    f"with {self.track_tolerance_m:g} m of room): what it "
                                    "flies there is not proven hidden")
            else:
                off[2] = max(off[2], round(d, 1))
        elif off is not None:
            off[1] = round(t, 3)
            self.event(v.sysid, f"back on its proven route after {t - off[0]:.1f} s, "
                                f"{off[2]:.0f} m off at most")

    def _passed(self, v, seq: int, timed: bool) -> None:
        """Item ``seq`` passed, and so every waypoint before it; only a reached item
        reported now is ``timed`` (measured on, for the vehicle's pace)."""
        of_item = v.mission.waypoint_of_item
        passed = []
        for item in range(min(seq, len(of_item) - 1), -1, -1):
            index = of_item[item]
            if index is None:
                continue
            if index in v.done:
                break                   # counted, and so is everything before it
            passed.append(index)
        for index in reversed(passed):
            v.done.add(index)
            w = v.route.waypoints[index]
            # only the one reported was reached now; those before it, passed unheard
            # (in a shadow), were reached earlier: timed now they read as a burst
            v.contact.mark(self.now(), w.t_s, self._own_clock(v),
                           timed=timed and index == passed[0])
            if w.snapshot:
                v.snapshots.append(Snapshot(round(self.now(), 3), w.lon, w.lat, w.alt_amsl,
                                            v.generation, index))

    # -- losses (flight loop) ---------------------------------------------------------
    def wait_settled(self, sysids, vertical: bool = True, timeout_s: float = SETTLE_S) -> None:
        """Give held vehicles time to brake before their positions are taken: until
        each reports moving slower than `SETTLED_MPS` (with ``vertical`` in 3-D: one
        still sinking is not where it will stand), ``timeout_s`` wall seconds at
        most; losses are looked for meanwhile (found by the caller's next step)."""
        end = time.monotonic() + timeout_s
        time.sleep(0.3)                 # the hold on its way, and a report after it
        while time.monotonic() < end:
            self.check_losses()
            if all(_speed(self.links[s].state, vertical) < SETTLED_MPS for s in sysids):
                return
            time.sleep(0.1)

    def check_losses(self) -> list:
        """Vehicles newly found lost: silent for ``lost_after_s`` (wall clock), in the
        air or landed with work still to fly (`awaited`: its next sortie); down at
        its base for a battery swap not yet seen (`swapping`), for ``swap_silence_s``:
        the swap powers most autopilots down. Each is also kept for `take_losses`,
        whoever called this."""
        lost = []
        awaited, swapping = self.awaited(), self.swapping()
        with self._lock:
            for sysid, v in self.vehicles.items():
                if v.state == LOST and self._heard_back(v):
                    self._rejoin(v)
                if v.finished and v.state != STRANDED and \
                        not (v.state == LANDED and sysid in awaited):
                    if v.state == LOST and v.lost_at_s is not None and not getattr(
                            v, "_reported", False):
                        v._reported = True
                        lost.append(sysid)
                    continue
                age, stalled = self._silence(sysid)
                swap = sysid in swapping
                self._note_power(v, age - stalled, swap)
                silent = age - stalled > self.lost_after_s
                if silent and not swap and self._as_planned(v, age):
                    continue
                if v.quiet is not None:     # heard again: its HEARTBEAT handler says so
                    if silent:
                        self._lose_overdue(v)
                        lost.append(sysid)
                    continue
                if age - stalled > (max(self.swap_silence_s, self.lost_after_s) if swap
                                    else self.lost_after_s):
                    v.lost_stalled_s = round(stalled, 3)
                    self._lose(v, f"nothing heard for {age:.1f} s"
                                  + (" since it landed for its battery swap" if swap else ""),
                               silence=True)
                    v._reported = True
                    lost.append(sysid)
            self._untaken.extend(lost)
        return lost

    def _as_planned(self, v, age) -> bool:
        """A silence inside a predicted radio shadow, not yet overdue: said once (out of
        contact, as planned, and when it is due back), not a loss. Only in the air: the
        plan predicts no silence on the ground (a vehicle silent at its base for its
        next sortie's upload once read as a shadow of that sortie, and was never lost)."""
        if v.quiet is None:
            # airborne stays set until relaunched; a held vehicle hovers where it was
            # heard, off its plan's clock (placed along its plan, one held for a
            # re-plan was taken into a shadow it never flew, and not lost)
            if not v.airborne or v.state in (LANDED, HOLDING):
                return False
            s = self.links[v.sysid].state
            lat, lon = getattr(s, "lat", None), getattr(s, "lon", None)
            heard, own = self._last_heard(v, s, age)
            v.quiet = v.contact.expected(heard, self.lost_after_s,
                                         None if lat is None else (lat, lon), own)
            if v.quiet is None:
                return False
            a, b = v.quiet.window
            self.event(v.sysid, f"out of contact, as planned: a radio shadow of {b - a:.0f} s "
                                f"predicted; due back by {v.quiet.due_s:.0f} s, overdue "
                                f"after {v.quiet.overdue_s:.0f} s at today's pace",
                       out_of_contact=True, heard_s=round(v.quiet.heard_s, 3),
                       due_s=round(v.quiet.due_s, 3))
            v.quiet_flown, v.quiet_at = (self.now() - v.quiet.heard_s) * v.contact.pace, \
                self.now()
        now = self.now()
        v.quiet_flown += (now - v.quiet_at) * self._pace_unheard(v)
        v.quiet_at = now
        return v.quiet_flown <= v.quiet.allowed_s

    def _own_clock(self, v) -> float | None:
        """The vehicle's own clock (s since boot) now: its latest report's, carried on
        at its clock's rate to now (None unknown). A waypoint's reached report carries
        no time: timed by the last position's, up to a fifth of a wall second older
        (20 s of its clock at 100x), progress over a few waypoints read up to twice
        the plan's, and a vehicle due back from a shadow 1.8 s (180 s of flight)
        before it was."""
        return _own_at(self.links[v.sysid].state, time.monotonic())

    def _last_heard(self, v, state, age) -> tuple:
        """(monitor s, its own clock then) of the last time a vehicle was heard: its
        last message, ``age`` s ago, or its last report with a time since boot,
        whichever is later (a sped-up simulator's HEARTBEATs come on the wall clock,
        its reports on its own)."""
        heard = self.now() - age
        boot_at = getattr(state, "boot_at", None)
        if boot_at is None:
            return heard, None
        report = boot_at - self.t0
        if report >= heard:
            return report, state.boot_s
        return heard, _own_at(state, heard + self.t0)

    def _pace_unheard(self, v) -> float:
        """Fleet seconds per monitor second of a silent vehicle: its own pace on its
        plan, at the clock rate the vehicles still heard run at now (one machine's
        simulated fleet slows together under load; real autopilots all run at 1)."""
        rates = sorted(u.contact.clock_rate for s, u in self.vehicles.items()
                       if u is not v and u.quiet is None and not u.finished
                       and self.links[s].silent_s() <= self.lost_after_s)
        if not rates:
            return v.contact.pace
        return rates[len(rates) // 2] * v.contact.pace / v.contact.clock_rate

    def _back_in_contact(self, v) -> None:
        q, v.quiet = v.quiet, None
        now = self.now()
        v.silences.append({"from_s": round(q.heard_s, 3), "to_s": round(now, 3),
                           "due_s": round(q.due_s, 3), "window": list(q.window)})
        self.event(v.sysid, f"back in contact after {now - q.heard_s:.0f} s out of contact, "
                            f"{abs(now - q.due_s):.0f} s {'before' if now <= q.due_s else 'after'}"
                            f" it was due (overdue after {q.overdue_s:.0f} s)")

    def _lose_overdue(self, v) -> None:
        q = v.quiet
        v.silences.append({"from_s": round(q.heard_s, 3), "to_s": None,
                           "due_s": round(q.due_s, 3), "window": list(q.window)})
        self._lose(v, f"overdue: last heard at {q.heard_s:.0f} s entering a predicted radio "
                      f"shadow, due back by {q.due_s:.0f} s, not heard by "
                      f"{q.overdue_s:.0f} s", due_s=round(q.due_s, 3), silence=True)
        v._reported = True

    def _heard_back(self, v) -> bool:
        """Lost for a silence, and heard again since, position included: a report
        newer than that HEARTBEAT (the link's position from before the silence
        would place it where it was)."""
        s = self.links[v.sysid].state
        boot_at = getattr(s, "boot_at", None)
        return v.silent_loss and v.heard_after_loss_s is not None and \
            boot_at is not None and boot_at - self.t0 >= v.heard_after_loss_s and \
            self.links[v.sysid].silent_s() <= self.lost_after_s

    def _rejoin(self, v) -> None:
        """A vehicle lost for a silence and heard again: in the air (flying on by
        itself, as its mission tells it), or landed at a base of its flight. Taken
        back under the monitor (and so the guard) and handed to the flight to be
        re-planned with the others (`take_rejoined`); down anywhere else it stays
        lost."""
        s = self.links[v.sysid].state
        grounded = self._on_ground(s)
        if s.armed and grounded and self.on_pad(v.sysid):
            return      # touching down at its base or lifting off: judged once it is not
        flying = bool(s.armed) and not grounded
        landed = not s.armed and self.on_pad(v.sysid)
        v.silent_loss = False                # judged once: a loss again is a new one
        if not (flying or landed):
            self.event(v.sysid, "heard again after it was declared lost, down away from "
                                "its bases: not taken back; bring it home by hand")
            return
        back = round(self.now(), 3)
        v.rejoins.append({"lost_at_s": v.lost_at_s, "reason": v.lost_reason,
                          "heard_s": v.heard_after_loss_s, "back_s": back,
                          "as": FLYING if flying else LANDED})
        v.state = FLYING if flying else LANDED
        v.lost_at_s = v.lost_reason = v.heard_after_loss_s = v.quiet = None
        v.disarmed_at_s, v._reported = None, False
        if landed:
            v.landed_at_s = back
        self.catch_up(v.sysid)
        self._rejoined.append(v.sysid)
        self.event(v.sysid, "rejoined: heard again after it was declared lost, "
                            f"{'flying' if flying else 'landed at its base'}; back under the "
                            "monitor and the separation guard, re-planned with the others",
                   rejoined=True)

    def catch_up(self, sysid) -> None:
        """Every waypoint before the item a vehicle flies now (MISSION_CURRENT) was
        passed, heard or not: a vehicle back from a silence is credited with what it
        flew unheard (its MISSION_ITEM_REACHED reports were lost with the link)."""
        with self._lock:
            v, seq = self.vehicles[sysid], self.links[sysid].state.mission_seq
            if v.mission is not None and seq is not None and int(seq) > 0:
                self._passed(v, int(seq) - 1, timed=False)

    def take_rejoined(self) -> list:
        """Vehicles taken back after a loss since the last call: the flight re-plans
        the fleet with them."""
        with self._lock:
            taken, self._rejoined = self._rejoined, []
        return taken

    def _note_power(self, v, silent_s, swap) -> None:
        """Say when a vehicle down for its battery swap falls silent (powered down,
        not lost yet), and when it is heard again."""
        if swap and silent_s > self.lost_after_s and v.powered_down_at_s is None:
            v.powered_down_at_s = round(self.now() - silent_s, 3)
            self.event(v.sysid, f"silent at its base for {silent_s:.0f} s: taken for its "
                                f"battery swap powering it down; lost if not heard again "
                                f"within {self.swap_silence_s:g} s")
        elif silent_s <= self.lost_after_s and v.powered_down_at_s is not None:
            self.event(v.sysid, f"heard again after {self.now() - v.powered_down_at_s:.0f} s "
                                "powered down for its battery swap")
            v.powered_down_at_s = None

    def silent(self, sysid) -> bool:
        """Nothing heard from ``sysid`` for ``lost_after_s`` of the time this ground
        station was running (`StallClock`: a starved ground station hears nothing
        from anyone, and would otherwise lose its whole fleet at once)."""
        age, stalled = self._silence(sysid)
        return age - stalled > self.lost_after_s

    def _silence(self, sysid) -> tuple:
        """(seconds since anything was heard from ``sysid``, of them the seconds this
        ground station stood still); the stall is only looked up past
        ``lost_after_s``."""
        age = self.links[sysid].silent_s()
        if age <= self.lost_after_s:
            return age, 0.0
        return age, self.stalls.stalled(time.monotonic() - age)

    def planned_at(self, sysid) -> float | None:
        """Where on its plan's clock a vehicle out of contact as planned is now (its
        planned trajectory stays its own until it is declared lost); None for one
        heard."""
        v = self.vehicles.get(sysid)
        if v is None or v.quiet is None or v.state == LOST:
            return None
        # where it was when last heard, and as far as the overdue count has it flown
        # since (`_as_planned`), on to now
        return v.quiet.fleet_s + v.quiet_flown + \
            (self.now() - v.quiet_at) * self._pace_unheard(v)

    def planned_position(self, sysid) -> tuple | None:
        """(lon, lat, alt AMSL) of a vehicle out of contact as planned, on its planned
        trajectory (`planned_at`); None for one heard."""
        at = self.planned_at(sysid)
        rows = self.vehicles[sysid].trajectory if at is not None else None
        if rows is None:
            return None
        return tuple(float(np.interp(at, rows[:, 0], rows[:, k])) for k in (1, 2, 3))

    def take_losses(self) -> list:
        """Vehicles found lost since the last call, by any `check_losses` (a loss
        found while waiting on other vehicles is not forgotten): the flight
        re-tasks once for them all."""
        with self._lock:
            taken, self._untaken = self._untaken, []
        return taken

    def losses_waiting(self) -> bool:
        """Losses found that `take_losses` has not handed out yet."""
        with self._lock:
            return bool(self._untaken)

    def _lose(self, v, reason: str, silence: bool = False, **extra) -> None:
        v.state = LOST
        v.lost_at_s = round(self.now(), 3)
        v.lost_reason = reason
        v.silent_loss = silence
        self.event(v.sysid, LOST, reason=reason, last_heartbeat_s=v.last_heartbeat_s, **extra)

    # -- views ------------------------------------------------------------------------
    def survivors(self) -> list:
        with self._lock:
            return [s for s, v in self.vehicles.items() if v.state != LOST]

    def all_finished(self) -> bool:
        with self._lock:
            return all(v.finished for v in self.vehicles.values())

    def status_rows(self) -> list:
        """One row per vehicle for the status table."""
        rows = []
        with self._lock:
            for sysid, v in sorted(self.vehicles.items()):
                s = self.links[sysid].state
                age = self.links[sysid].heartbeat_age()
                items = mission_items(v.mission)
                rows.append({
                    "sysid": sysid, "vehicle": v.vehicle_id, "mode": s.mode or "?",
                    "item": f"{_or_dash(shown_item(s, items))}/{items}",
                    "mission": v.generation,
                    "snapshots": f"{len(v.snapshots)} ({v.snapshots_done}/{v.snapshot_total})",
                    "alt": s.relative_alt, "heartbeat_s": age, "state": v.state,
                    "battery": s.battery_pct})
        return rows
