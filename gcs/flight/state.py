"""What every part of one flight reads: `FlightState`, and where a vehicle is
along its route (`next_waypoint`, `homebound`, `own_clock`).

The parts of a flight (preflight, departures, batteries, holds, the report)
each own one concern and keep their own records; what they share is here: the
plan and its context, the options, the monitor and the fleet clock, and the
sorties each vehicle has still to fly, which the departures, the batteries and
a re-plan change.
"""

import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

from gcs.monitor import LOST
from gcs.retask import in_parallel
from missions.build import MissionOptions
from planner.context import PlanningContext
from planner.pipeline import load_context
from planner.plan import Plan

from .options import FlightError

#: wall seconds between two looks for a loss while a failed vehicle is waited for
LOOP_WAIT_S = 0.1


@dataclass
class FlightState:
    plan_dir: Path
    plan: Plan
    options: object                  # `FlyOptions`
    monitor: object                  # `gcs.monitor.Monitor`
    clock: object                    # `gcs.clock.FleetClock`
    log: object                      # text -> None
    ctx: PlanningContext | None = None
    later: dict = field(default_factory=dict)    # sysid -> [(offset, sortie route)] to come
    offset: dict = field(default_factory=dict)   # sysid -> fleet s of its route's t = 0
    spent: set = field(default_factory=set)      # sent home by the battery watch: stay down
    _ready: threading.Event = field(default_factory=threading.Event)
    _error: Exception | None = None

    @property
    def params(self) -> dict:
        return self.plan.params

    @property
    def separation_m(self) -> float:
        return float(self.plan.params.get("separation_m", 0.0))

    @property
    def mission_options(self) -> MissionOptions:
        """Fly at the speed the plan's times assume, as `gcs plan` writes the files."""
        return MissionOptions(speed_mps=self.plan.params.get("speed_mps"))

    def load_context(self) -> PlanningContext:
        """The plan's `PlanningContext`: given (`gcs demo`), or read from its folder (a
        folder of only plan.json and terrain.tif: its stages run again)."""
        if self.ctx is None:
            self.ctx = load_context(self.plan_dir, self.plan)
        return self.ctx

    def prepare_context(self) -> None:
        """The travel times between viewpoints (of an area planned in parts: the
        overlay each part's times come from), which only re-planning needs:
        computed while the vehicles start, so that a loss finds them ready."""
        try:
            if self.ctx.in_parts:
                self.ctx.viewpoint_overlay()
            else:
                self.ctx.travel  # noqa: B018 - computed once, kept by the context
        except Exception as exc:  # reported when the context is needed
            self._error = exc
        self._ready.set()

    def context(self) -> PlanningContext:
        """The context, once `prepare_context` is done (its error raised here)."""
        self._ready.wait()
        if self._error is not None:
            raise self._error
        return self.ctx

    def awaited(self) -> set:
        """Vehicles down between two sorties, still part of the flight: one that goes
        silent there is lost (and re-planned for), not waited for."""
        m = self.monitor
        return {s for s, parts in list(self.later.items())
                if parts and m.vehicles[s].state != LOST}

    def on_every(self, fn, what, expected) -> None:
        """fn on every vehicle not lost, at once. A vehicle that fails and then falls
        silent was lost during this stage (the flight goes on); any other failure
        stops it."""
        sysids = [s for s, v in sorted(self.monitor.vehicles.items()) if v.state != LOST]
        self.lost_or_failed(fn, sysids, what, expected)

    def lost_or_failed(self, fn, sysids, what, expected) -> list:
        """fn on ``sysids`` at once; those that fell silent meanwhile (now or within
        ``lost_after_s`` of failing) are lost, returned, and re-tasked for by the
        flight loop; any other failure stops the flight (FlightError for an
        ``expected`` one)."""
        m = self.monitor
        errors = in_parallel(fn, sysids, m)  # a vehicle falling silent is not waited for
        failed = {s: e for s, e in errors.items() if e is not None}
        end = time.monotonic() + self.options.lost_after_s + 1.0
        while failed and time.monotonic() < end and any(m.vehicles[s].state != LOST
                                                        for s in failed):
            m.check_losses()
            time.sleep(LOOP_WAIT_S)
        for sysid, exc in sorted(failed.items()):
            if m.vehicles[sysid].state != LOST:
                if isinstance(exc, expected):
                    raise FlightError(f"{what} failed: {exc}") from None
                raise exc
        lost = [s for s in sysids if m.vehicles[s].state == LOST]
        for sysid in lost:
            error = errors.get(sysid)  # none when it fell silent before failing
            m.event(sysid, f"lost during {what}", **({"error": str(error)} if error else {}))
        return lost


def next_waypoint(monitor, sysid) -> int:
    """Index of the route waypoint a vehicle flies to next: the one after the last it
    reached, or the one its mission's current item (MISSION_CURRENT) is, when
    further on. A link silent for a while loses the reached reports of what was
    flown meanwhile: heard again 200 s of flight later (2 s at 100 x), a vehicle was
    taken for still flying to the waypoint before the silence, 5 minutes late, and
    brought home early."""
    v = monitor.vehicles[sysid]
    after = max(v.done) + 1 if v.done else 0
    seq = monitor.links[sysid].state.mission_seq
    of_item = v.mission.waypoint_of_item if v.mission is not None else None
    if seq is None or not of_item:
        return after
    ahead = next((i for i in of_item[int(seq):] if i is not None), None)
    return after if ahead is None else max(after, ahead)


def homebound(monitor, sysid) -> bool:
    """Nothing left to photograph: on its way home."""
    waypoints = monitor.vehicles[sysid].route.waypoints
    return not any(w.snapshot for w in waypoints[next_waypoint(monitor, sysid):])


def own_clock(monitor, sysid):
    """The vehicle's own clock (s since its boot) at its last position report."""
    track = monitor.vehicles[sysid].track
    return track[-1][4] if track else None
