"""Along its route: the missions a vehicle is given (a re-plan, a next
sortie, a segment, a re-launch), the waypoints it passes and the snapshots taken
there, and whether it keeps to its route's proven legs (`gcs.corridor`)."""

from gcs.corridor import POSITION_MARGIN_M, ProvenPath
from missions.returns import landing_gaps

from .records import LANDED, STARTING, WAITING, Snapshot


class Routes:
    """The `Monitor`'s part that follows each vehicle along its mission."""

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
