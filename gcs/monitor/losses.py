"""Losses, on the wall clock: a vehicle silent past ``lost_after_s`` (of the time
the ground station itself ran: `StallClock`), or past its battery swap's
silence; one heard again after a loss for a silence is taken back (`_rejoin`)
where it flies on or stands at a base of its flight. A silence the plan predicts is
judged in `gcs.monitor.shadows`."""

import collections
import math
import threading
import time

from .records import FLYING, LANDED, LOST, SETTLE_S, SETTLED_MPS, STRANDED


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


def _speed(state, vertical: bool) -> float:
    """m/s from the last GLOBAL_POSITION_INT: ground speed, or 3-D with ``vertical``."""
    if vertical and state.velocity is not None:
        return math.hypot(*state.velocity)
    return math.inf if state.groundspeed is None else state.groundspeed


class Losses:
    """The `Monitor`'s part that finds the vehicles lost, and takes back the ones
    heard again."""

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
                    v.last_heard_s = round(self.now() - age, 3)
                    self._lose(v, f"nothing heard for {age:.1f} s"
                                  + (" since it landed for its battery swap" if swap else ""),
                               silence=True)
                    v._reported = True
                    lost.append(sysid)
            self._untaken.extend(lost)
        return lost

    def _lose(self, v, reason: str, silence: bool = False, **extra) -> None:
        v.state = LOST
        v.lost_at_s = round(self.now(), 3)
        v.lost_reason = reason
        v.silent_loss = silence
        self.event(v.sysid, LOST, reason=reason, last_heartbeat_s=v.last_heartbeat_s, **extra)

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
        grounded, pad = self._on_ground(s), self.on_pad(v.sysid)
        if s.armed and grounded and pad:
            return      # touching down at its base or lifting off: judged once it is not
        flying = bool(s.armed) and not grounded
        landed = not s.armed and pad
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
