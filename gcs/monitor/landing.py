"""Landing or crash: a vehicle that touches the ground (disarmed after flying, or
below the plan's terrain) has landed only at a base of its flight after its
mission's last waypoint; anywhere else, or earlier, it crashed, or a failsafe put
it down in the field: lost to the flight either way."""

import math

from common.geo import distance_m

from .records import CRASH_MARGIN_M, DISARM_REPORTS, LANDED, LANDED_AGL_M, LAUNCH_RADIUS_M


class Landing:
    """The `Monitor`'s part that judges a vehicle on the ground, or going there."""

    def _judge_disarm(self, v, agl) -> None:
        """Disarmed after flying: on the ground or still falling? On the ground it
        landed only at a base of its flight after its last waypoint; anywhere else,
        or before, it crashed (lost)."""
        s = self.links[v.sysid].state
        height = self._height(s)
        touched = (agl is not None and abs(agl) <= LANDED_AGL_M) or \
            (height is not None and height <= LANDED_AGL_M) or getattr(s, "landed", None) is True
        if not touched:
            if v.disarmed_reports >= DISARM_REPORTS:
                self._lose(v, f"disarmed in the air ({agl or 0.0:.0f} m above home)")
            return
        away = self._from_base(v, s)
        if away is not None and away > LAUNCH_RADIUS_M:
            return self._lose(v, self._down_said(v, away) or
                              f"crashed: touched the ground {away:.0f} m from its base")
        final, progress = v.final_approach_seq(), self._progress(v, s)
        if final is not None and (progress is None or progress < final) and \
                not self._failsafe_return(v):
            where = "nothing" if progress is None else f"item {progress}"
            if v.unheard_from_s is None:
                return self._lose(v, f"crashed: touched the ground before its last item "
                                     f"({where} of {final} reached)")
            self._landed_unheard(v, progress, final, where)
        v.state = LANDED
        v.landed_at_s = round(self.now(), 3)
        self.event(v.sysid, LANDED, battery_pct=s.battery_pct)

    def _landed_unheard(self, v, progress, final, where) -> None:
        """Heard again after a radio silence, down at its base before its last item: it
        came home unheard (a failsafe's return whose mode the silence hid: the link
        failsafe fires in the silence itself), not a crash; what it flew there is not
        known, so not proven hidden (a problem of the flight, `down_unheard`)."""
        v.down_unheard.append({"t_s": round(self.now(), 3), "from_s": round(v.unheard_from_s, 3),
                               "item": progress, "final": final})
        self.event(v.sysid, f"down at its base before its last item ({where} of {final} "
                            f"reached), heard again after a silence from "
                            f"{v.unheard_from_s:.0f} s: it came home unheard (a failsafe's "
                            "return?), its way not proven hidden")
        v.unheard_from_s = None

    def _below_terrain(self, v, s) -> None:
        """Away from launch and below the terrain + CRASH_MARGIN_M: it hit the ground."""
        height = self._height(s)
        if height is None or height >= CRASH_MARGIN_M:
            return
        away = self._from_base(v, s)
        if away is None or away > LAUNCH_RADIUS_M:
            self._lose(v, self._down_said(v, away) or f"crashed: {height:.1f} m above the "
                          f"terrain ({s.alt_amsl:.1f} m AMSL, {away or 0.0:.0f} m from launch)")

    def _on_ground(self, s) -> bool:
        """By its height above the plan's terrain, fresh with its position; without a
        terrain by its own word (EXTENDED_SYS_STATE), else by its height above home,
        which is no height above the ground: a route over a valley flies at home
        height (a vehicle heard back there was once judged down in the field)."""
        height = self._height(s)
        if height is not None:
            return height <= LANDED_AGL_M
        if getattr(s, "landed", None) is not None:
            return s.landed
        agl = getattr(s, "relative_alt", None)
        return agl is not None and abs(agl) <= LANDED_AGL_M

    def _height(self, s):
        """Height (m) above the plan's terrain, None when unknown."""
        if self.ground is None or getattr(s, "lat", None) is None or s.alt_amsl is None:
            return None
        ground = self.ground(s.lat, s.lon)
        return None if ground is None or not math.isfinite(ground) else s.alt_amsl - ground

    def on_pad(self, sysid) -> bool:
        """Down at a base of its flight (within `LAUNCH_RADIUS_M`, at home height), whether
        or not its landing has been told yet (the disarm comes a few seconds after
        the touchdown)."""
        v, s = self.vehicles[sysid], self.links[sysid].state
        planned = self.planned_position(sysid)
        if planned is not None:     # out of contact as planned: where its plan has it
            return self._planned_on_pad(v, planned)
        agl, away = getattr(s, "relative_alt", None), self._from_base(v, s)
        return agl is not None and abs(agl) <= LANDED_AGL_M and away is not None \
            and away <= LAUNCH_RADIUS_M

    @staticmethod
    def _planned_on_pad(v, planned) -> bool:
        """Whether (lon, lat, alt AMSL) ``planned`` is down on a base of its route (a
        silent vehicle's plan landed it: in nobody's column until its next takeoff)."""
        lon, lat, alt = planned
        points = [getattr(v.route, "launch", None), getattr(v.route, "land", None)]
        return any(p is not None and abs(alt - p.alt_amsl) <= LANDED_AGL_M and
                   distance_m(p.lat, p.lon, lat, lon) <= LAUNCH_RADIUS_M for p in points)

    @staticmethod
    def _from_base(v, s):
        """Horizontal distance (m) from the nearer of its bases (`Vehicle.bases`: the
        launch point, the base a sortie lands at; home where the route has none)."""
        home = getattr(s, "home", None)
        bases = v.bases or ([home[:2]] if home is not None else [])
        if not bases or getattr(s, "lat", None) is None:
            return None
        return min(distance_m(b[0], b[1], s.lat, s.lon) for b in bases)

    @staticmethod
    def _progress(v, s):
        """The furthest item of the current mission the vehicle is known to have
        reached or be flying to (MISSION_ITEM_REACHED, MISSION_CURRENT)."""
        seen = set(v.reached)
        if getattr(s, "mission_seq", None) is not None:
            seen.add(int(s.mission_seq))
        return max(seen) if seen else None

    def in_failsafe(self, sysid) -> bool:
        """Flying in a failsafe's mode now (SmartRTL, RTL, LAND): the autopilot's own
        return, which no command of the ground station should undo."""
        link = self.links.get(sysid)
        modes = getattr(getattr(link, "profile", None), "failsafe_modes", {})
        return link is not None and link.state.mode in modes

    def _failsafe_return(self, v) -> bool:
        """Its last mode was a failsafe's (SmartRTL, RTL, LAND): down at a base before
        its last item, it came home on the autopilot's own; elsewhere, it is down in
        the field (lost to the flight all the same), not crashed."""
        modes = getattr(getattr(self.links.get(v.sysid), "profile", None), "failsafe_modes", {})
        return bool(v.uncommanded) and v.uncommanded[-1][1] in modes

    def _down_said(self, v, away) -> str | None:
        """A vehicle a failsafe put down away from its bases: why it is lost to the
        flight (None when no failsafe did)."""
        if not self._failsafe_return(v):
            return None
        return (f"down in the field: a failsafe's {v.uncommanded[-1][1]} put it on the ground "
                f"{away or 0.0:.0f} m from its base")
