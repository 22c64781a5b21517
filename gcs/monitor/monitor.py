"""The `Monitor`: one object, one lock, over the telemetry of every vehicle of a
flight. Here: following a vehicle's link, the event log, the flight state the
flight sets, the views of the status table."""

import threading
import time

from gcs.contact import Contact
from gcs.corridor import ProvenPath

from .landing import Landing
from .losses import Losses, StallClock
from .records import LOST, SWAP_SILENCE_S, VehicleProgress
from .route import Routes
from .shadows import Shadows
from .telemetry import Telemetry


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


class Monitor(Telemetry, Landing, Losses, Shadows, Routes):
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
