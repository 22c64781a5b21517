"""Out of contact as planned: a silence that starts where the plan predicts a
radio shadow (`gcs.contact`) is an event, not a loss, until the vehicle is
overdue at its measured pace; meanwhile its plan says where it is
(`planned_at`, `planned_position`). The vehicle's own clock, carried on from
its last report, times it."""

import time

import numpy as np

from .records import HOLDING, LANDED, LOST


def _own_at(state, mono: float) -> float | None:
    """A vehicle's own clock (s since boot) at ``mono`` (time.monotonic()): its latest
    report's, carried on at its clock's rate; None unknown."""
    boot_s, boot_at = getattr(state, "boot_s", None), getattr(state, "boot_at", None)
    if boot_s is None or boot_at is None:
        return None
    return boot_s + (mono - boot_at) * getattr(state, "clock_rate", 1.0)


class Shadows:
    """The `Monitor`'s part that follows a silent vehicle along its plan."""

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
            v.quiet = self._expected(v, *self._last_heard(v, self.links[v.sysid].state, age))
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

    def _back_in_contact(self, v) -> None:
        q, v.quiet = v.quiet, None
        now = self.now()
        v.unheard_from_s = q.heard_s      # until a position says it is still in the air
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

    def near_shadow(self, sysid) -> bool:
        """Whether a vehicle heard now is in a radio shadow its plan predicts or about
        to enter one (a silence starting now would be as planned: `Contact.expected`).
        Held there, it would hover out of contact, and the link-loss failsafe fires in
        the hold mode (ArduPilot's GUIDED has no FS_OPTIONS bit to hold on): the
        separation guard gives it the right of way."""
        v = self.vehicles.get(sysid)
        if v is None or v.quiet is not None or not v.contact.windows:
            return False
        return self._expected(v, self.now(), self._own_clock(v)) is not None

    def _expected(self, v, heard_s, own_s):
        """The predicted silence `v` is in, heard at ``heard_s`` (its own clock then at
        ``own_s``) where its latest position puts it (`Contact.expected`); None: none."""
        s = self.links[v.sysid].state
        lat, lon = getattr(s, "lat", None), getattr(s, "lon", None)
        return v.contact.expected(heard_s, self.lost_after_s,
                                  None if lat is None else (lat, lon), own_s)

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
