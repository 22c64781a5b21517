"""Telemetry, on the links' reader threads: each message kind a vehicle sends has
its handler (`Telemetry._HANDLERS`), run under the monitor's lock. A handler
records what the message says (the track, the items reached, camera feedback, the
autopilot's words) and asks the judgments of the other parts of the `Monitor`
about it (a landing, a crash, a return from a radio shadow, the route)."""

import re

from gcs.link import has_position
from gcs.mavlink import M

from .records import LANDED, LANDED_AGL_M, LIFTOFF_M, LOST, STRANDED, TRACK_PERIOD_S


def _uncommanded_said(profile, mode: str) -> str:
    """The event of a flying vehicle seen in ``mode``, which gcs did not command: a
    failsafe's mode (the profile's ``failsafe_modes``) says what the firmware flies
    in it."""
    flies = profile.failsafe_modes.get(mode)
    if flies is not None:
        return (f"failsafe: flying in {mode}, a mode gcs did not command ({flies}): the "
                "autopilot's own action, proven hidden only where `gcs fly` found its "
                "failsafes hidden")
    return (f"flying in {mode}, a mode gcs did not command (a pilot's or a failsafe's): "
            "what it flies there is not proven hidden")


def _note_airborne(v, armed: bool, agl) -> None:
    """Armed away from home height, above it or below it (a route over lower ground
    than the launch point): flying. Judged on every position report too: at a high
    speed-up a heartbeat may come only after the vehicle has dropped below home."""
    if armed and agl is not None and abs(agl) > LANDED_AGL_M:
        v.airborne = True


class Telemetry:
    """The `Monitor`'s part that reads the messages of its vehicles' links."""

    def _on(self, sysid: int, msg) -> None:
        kind = msg.get_type()
        handler = self._HANDLERS.get(kind)
        if handler is not None:
            with self._lock:
                v = self.vehicles.get(sysid)
                if v is not None and v.state != LOST:
                    handler(self, v, msg)
                elif v is not None and kind == "HEARTBEAT" and v.heard_after_loss_s is None:
                    v.heard_after_loss_s = round(self.now(), 3)
                    self.event(sysid, f"heard again after it was declared lost ({v.lost_reason})"
                               + ("" if v.silent_loss else ": it came down where it is not "
                                  "flown or guarded by this flight; bring it home by hand"),
                               heard_after_loss=True)

    def _heartbeat(self, v, msg) -> None:
        v.last_heartbeat_s = self.now()
        if v.quiet is not None:
            self._back_in_contact(v)
        armed = bool(msg.base_mode & M.MAV_MODE_FLAG_SAFETY_ARMED)
        agl = self.links[v.sysid].state.relative_alt
        _note_airborne(v, armed, agl)
        if v.airborne and armed:
            self._judge_mode(v)
        if v.airborne and not armed and v.state != LANDED and v.disarmed_at_s is None:
            # position reports lag the touchdown: judge by the next ones
            v.disarmed_at_s = self.now()
            v.disarmed_reports = 0
            self._judge_disarm(v, agl)

    def _judge_mode(self, v) -> None:
        """In the air in a mode the ground station did not command (a pilot took
        over, a failsafe fired: RTL, LAND): what it flies now is not proven hidden.
        Each such mode is an event and a problem of the flight (`uncommanded`)."""
        link = self.links[v.sysid]
        profile = getattr(link, "profile", None)
        mode = link.state.mode
        if profile is None or mode is None or mode in profile.commanded_modes:
            return
        if not v.uncommanded or v.uncommanded[-1][1] != mode:
            v.uncommanded.append((round(self.now(), 3), mode))
            self.event(v.sysid, _uncommanded_said(profile, mode))

    def _position(self, v, msg) -> None:
        if not has_position(msg):
            return                     # no position yet (ArduPilot before its EKF origin)
        t = self.now()
        agl = msg.relative_alt * 1e-3
        armed = self.links[v.sysid].state.armed
        _note_airborne(v, armed, agl)
        if armed and agl > LIFTOFF_M and v.lifted_at_s is None:
            v.lifted_at_s = t
            if not v.done:          # the route's takeoff: its first progress on the fleet clock
                v.contact.mark(t, getattr(v.route, "takeoff_s", 0.0), self._own_clock(v),
                               timed=False)     # seen once its HEARTBEAT says it armed
        if armed and v.unheard_from_s is not None and \
                not self._on_ground(self.links[v.sysid].state):
            v.unheard_from_s = None     # heard in the air after its silence
        if v.airborne and v.state not in (LANDED, LOST):
            self._below_terrain(v, self.links[v.sysid].state)
            if v.state == LOST:
                return
            if v.state != STRANDED:
                self._judge_route(v, msg.lat * 1e-7, msg.lon * 1e-7, msg.alt * 1e-3, t)
        if v.disarmed_at_s is not None and v.state != LANDED:
            v.disarmed_reports += 1
            self._judge_disarm(v, agl)
        if v.track and t - v.track[-1][0] < TRACK_PERIOD_S:
            return
        # the vehicle's own clock too: mission time, which runs faster than the wall
        # clock in a sped-up simulation
        boot = getattr(msg, "time_boot_ms", None)
        v.track.append((round(t, 3), msg.lon * 1e-7, msg.lat * 1e-7, msg.alt * 1e-3,
                        None if boot is None else round(boot * 1e-3, 3)))
        # its clock's rate (a sped-up simulator, slower on a busy machine), as its link
        # measures it
        if boot is not None:
            v.contact.set_clock_rate(getattr(self.links[v.sysid].state, "clock_rate", 1.0))

    def _reached(self, v, msg) -> None:
        """An item reached: its waypoint, and every waypoint of the mission before it
        not counted yet, since a mission is flown in order. PX4 reports a waypoint
        followed by DO commands (the camera) once they are done, with the last
        one's number, and only the latest item reached when several are reached
        between two of its reports (close waypoints)."""
        seq = int(msg.seq)
        if seq in v.reached:
            return
        v.reached.add(seq)
        self._passed(v, seq, timed=True)

    def _camera(self, v, msg) -> None:
        if msg.get_type() == "CAMERA_FEEDBACK":
            lat, lon, alt = msg.lat * 1e-7, msg.lng * 1e-7, msg.alt_msl
        else:
            lat, lon, alt = msg.lat * 1e-7, msg.lon * 1e-7, msg.alt * 1e-3
        v.camera.append((round(self.now(), 3), lon, lat, alt))

    def _text(self, v, msg) -> None:
        """A STATUSTEXT in which the autopilot says a failsafe fired or its return is
        gone (the profile's ``failsafe_texts``): an event, in its words."""
        profile = getattr(self.links.get(v.sysid), "profile", None)
        pattern = getattr(profile, "failsafe_texts", None)
        text = str(getattr(msg, "text", ""))
        if pattern and re.search(pattern, text):
            self.event(v.sysid, f"failsafe: the autopilot says \"{text}\"")

    _HANDLERS = {"HEARTBEAT": _heartbeat, "GLOBAL_POSITION_INT": _position,
                 "MISSION_ITEM_REACHED": _reached, "CAMERA_FEEDBACK": _camera,
                 "CAMERA_IMAGE_CAPTURED": _camera, "STATUSTEXT": _text}
