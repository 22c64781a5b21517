"""Routes longer than a vehicle holds, flown in segments (`missions.segments`).

Each vehicle's capacity is learned, never assumed: the first upload of a flight
goes up whole; a vehicle that refuses it for want of space (NO_SPACE) says how
many items it holds (ArduPilot's STATUSTEXT) or is asked (MISSION_COUNT probes,
`gcs.mission_protocol.learn_capacity`), and that is kept for the flight. A route
that does not fit is flown in segments: the first is uploaded before takeoff;
when the vehicle flies the last leg of a segment, the next one goes up in
flight with the same sequence as re-tasking (`gcs.retask`): hold (the
firmware's hold mode: ArduPilot applies an upload item by item), upload and
read back, current item = the first flown, the mission mode again. A vehicle
whose next segment is late waits at the end of its segment, a proven hidden
waypoint. The next segment starts where the vehicle holds, on its proven leg
(`missions.segments`: PX4 would otherwise climb straight up first). Every
segment is a `missions.check.CheckedMission` (the gate). A loss
during a segment upload is handled as one during re-tasking: the flight
re-tasks the survivors, the held vehicle among them.
"""

import time
from dataclasses import asdict, dataclass

from gcs import commands
from gcs.mavlink import M
from gcs.mission_protocol import MissionError, known_capacity, learn_capacity, upload_verified
from gcs.monitor import FLYING, HOLDING, LOST


@dataclass
class SegmentUpload:
    """One segment sent in flight, as written to flight.json."""

    t_s: float
    sysid: int
    segment: int           # its number along the route: 1 = the first (uploaded on the ground)
    first_waypoint: int    # route waypoint it starts at
    items: int
    upload_s: float        # upload and read-back, wall s
    held_s: float          # from the hold to the mission mode again, wall s
    why: str = "next"      # or "from here": the same segment again, from where it held


def upload_route(link, missions, protocol=None, on_capacity=None, limit=None):
    """Upload the first mission of ``missions`` (a `missions.segments.RouteMissions`)
    to ``link``: the whole route unless the vehicle is known to hold fewer items
    (or ``limit``: at most that many per upload); on a NO_SPACE refusal its
    capacity is learned and the first segment goes up instead. Returns the
    CheckedMission uploaded. ``on_capacity(capacity, how)`` is told when a
    capacity is learned."""
    protocol = protocol or {}
    mission = missions.first(segment_capacity(link, limit))
    try:
        upload_verified(link, mission, **protocol)
        return mission
    except MissionError as exc:
        if exc.result != M.MAV_MISSION_NO_SPACE:
            raise
        capacity = learn_capacity(link, len(mission), exc.capacity, **protocol)
        if on_capacity is not None:
            on_capacity(capacity, "said" if exc.capacity else "probed")
    mission = missions.first(_least(capacity, limit))
    upload_verified(link, mission, **protocol)
    return mission


def segment_capacity(link, limit=None):
    """Items a segment for ``link``'s vehicle may have: what it is known to hold, or
    ``limit`` if fewer (None: no limit known)."""
    return _least(known_capacity(link), limit)


def _least(capacity, limit):
    """The smaller of two item limits, either of which may be None (none)."""
    known = [c for c in (capacity, limit) if c is not None]
    return min(known) if known else None


class Segments:
    """Sends each vehicle its next segment in flight (see module doc).

    ``routes[sysid]``: the `RouteMissions` the vehicle flies now (set at the start
    and by every re-tasking); `due` says who needs its next segment, `switch`
    sends it."""

    def __init__(self, monitor, protocol=None, limit=None):
        """``limit``: items per upload at most (``gcs fly --max-items``), below what
        the vehicles hold."""
        self.monitor = monitor
        self.limit = limit
        self.protocol = protocol or {}
        self._retries = self.protocol.get("retries", commands.RETRIES)
        self.routes = {}
        self.uploads = []           # [SegmentUpload]

    def fly(self, sysid, missions) -> None:
        """From now on ``sysid`` flies ``missions`` (its uploaded mission is the first)."""
        self.routes[sysid] = missions

    def due(self) -> list:
        """Vehicles flying a segment that is not the last, on its last leg (or past)."""
        m = self.monitor
        out = []
        for sysid, v in sorted(m.vehicles.items()):
            mission = v.mission
            if v.state != FLYING or getattr(mission, "final", True) or sysid not in self.routes:
                continue
            last = _last_position_seq(mission)
            seq = m.links[sysid].state.mission_seq
            reached = max(v.reached) if v.reached else None
            if last is not None and ((seq is not None and seq >= last)
                                     or (reached is not None and reached >= last)):
                out.append(sysid)
        return out

    def switch(self, sysids, parallel) -> list:
        """Send each of ``sysids`` its next segment; ``parallel(fn, sysids)`` runs
        fn on them at once, watching for losses ({sysid: exception or None}).
        Returns the vehicles found lost meanwhile (the caller re-tasks); a failure
        of a vehicle still heard from raises it."""
        m = self.monitor
        errors = parallel(self._switch_one, sysids)
        lost = sorted(set(m.check_losses()) | {s for s in sysids
                                               if m.vehicles[s].state == LOST})
        if lost:
            return lost
        for sysid, exc in sorted(errors.items()):
            if exc is not None:
                raise exc
        return []

    def _switch_one(self, sysid) -> None:
        m = self.monitor
        t0 = time.perf_counter()
        commands.set_mode(m.links[sysid], commands.autopilot(m.links[sysid]).hold_mode,
                          retries=self._retries)
        m.set_state(sysid, HOLDING)
        self._from_here(sysid, t0, next_segment=True)

    def can_fly_on_here(self, sysid) -> bool:
        """Whether `fly_on_here` can: the vehicle holds past its route's first
        waypoint (before it, its mission's takeoff is flown again as it is)."""
        start, _ = self.next_start(sysid) if sysid in self.routes else (None, None)
        return start is not None and start != self.routes[sysid].fly[0]

    def fly_on_here(self, sysid) -> None:
        """A held vehicle flies on by the rest of its route uploaded from where it
        holds (the firmware would climb straight up first otherwise: the profile's
        `resume_climbs_above_m`); it stays the same segment."""
        self._from_here(sysid, time.perf_counter(), next_segment=False)

    def _from_here(self, sysid, t0, next_segment) -> None:
        """Upload the held vehicle's route from where it holds (the next segment, or
        its current one again) and fly it."""
        m = self.monitor
        link, v = m.links[sysid], m.vehicles[sysid]
        profile = commands.autopilot(link)
        m.wait_settled([sysid])         # where it stands, not a report from before its brake
        start, taken = self.next_start(sysid)
        capacity = _least(known_capacity(link) or len(v.mission), self.limit)
        index = v.mission.segment + (1 if next_segment else 0)
        mission = self.routes[sysid].segment(capacity, start, index, taken,
                                             here=_where(link.state))
        t1 = time.perf_counter()
        upload_verified(link, mission, **self.protocol)
        upload_s = time.perf_counter() - t1
        m.next_segment(sysid, mission, counted=next_segment)
        commands.set_current(link, profile.first_item, retries=self._retries)
        commands.set_mode(link, profile.mission_mode, retries=self._retries)
        m.set_state(sysid, FLYING)
        record = SegmentUpload(round(m.now(), 3), sysid, index + 1, start, len(mission),
                               round(upload_s, 3), round(time.perf_counter() - t0, 3),
                               "next" if next_segment else "from here")
        self.uploads.append(record)
        m.event(sysid, "next segment uploaded" if next_segment else
                "route uploaded from where it holds",
                **{k: v for k, v in asdict(record).items() if k not in ("t_s", "sysid")})

    def next_start(self, sysid) -> tuple:
        """(route waypoint the next segment starts at, whether its snapshot is taken):
        the waypoint the held vehicle was flying to (by MISSION_CURRENT and the
        waypoints it reached), the end of its segment at the latest."""
        m = self.monitor
        v = m.vehicles[sysid]
        mission, fly = v.mission, self.routes[sysid].fly
        last = mission.last_waypoint
        target = mission.first_waypoint
        seq = m.links[sysid].state.mission_seq
        of_item = mission.waypoint_of_item
        if seq is not None:
            ahead = [of_item[s] for s in range(max(0, seq), len(of_item))
                     if of_item[s] is not None]
            if ahead:
                target = max(target, ahead[0])
            else:
                target = last
        done = [i for i in v.done if mission.first_waypoint <= i <= last]
        if done:
            reached = max(done)
            after = [i for i in fly if i > reached]
            target = max(target, after[0] if after else reached)
        target = min(target, last)
        return target, target in v.done

    def report(self) -> list:
        return [asdict(u) for u in self.uploads]


def _where(state):
    """(lat, lon, alt AMSL) of a vehicle's last position report, None before one."""
    if state.lat is None or state.alt_amsl is None:
        return None
    return state.lat, state.lon, state.alt_amsl


def _last_position_seq(mission):
    """The item of the last waypoint of a mission (None without one)."""
    of_item = mission.waypoint_of_item
    found = [s for s, w in enumerate(of_item) if w is not None]
    return found[-1] if found else None


__all__ = ["SegmentUpload", "Segments", "upload_route"]
