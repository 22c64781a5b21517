"""Vehicles a re-plan left out, heard again (`LeftOut`).

A re-plan cannot command a vehicle out of contact as its plan predicts: it flies
its plan on, and the others are re-planned without counting what it will still
see (`gcs.retask`). Heard again, it may be needed: when its loss was the one
re-planned for, the vehicles re-tasked may not reach the coverage alone. The
fleet is then re-planned with it, but only when the plans in hand (each vehicle's
snapshots so far, the rest of its route and its later sorties) fall short of the
required coverage: a re-plan each time one comes back would send another into a
shadow each time (the fleet was once re-planned until its batteries ran out).
"""

import numpy as np

from gcs.monitor import LOST
from gcs.retask import original_outlook, points_xyz


class LeftOut:
    """Who the last re-plan left out, and whether one heard again calls for another."""

    def __init__(self, state, context):
        """``context()``: the plan's `PlanningContext` (loaded on first use)."""
        self.state = state
        self.context = context
        self.waiting = set()
        self.home = False             # the last re-plan sent the fleet home

    def after(self, record, home: bool = False) -> None:
        """A re-plan was made (`gcs.retask.Retask`; ``home``: the fleet sent home): its
        left-out vehicles are watched (and the earlier ones, now in it or left out
        again, no longer)."""
        self.waiting, self.home = set(record.left_out), home

    def short(self) -> bool:
        """A vehicle left out is heard again, and the plans in hand fall short of the
        required coverage: said, and True (re-plan the fleet with it)."""
        m = self.state.monitor
        back = sorted(s for s in self.waiting
                      if m.vehicles[s].state != LOST and m.planned_at(s) is None)
        self.waiting -= set(back) | {s for s in self.waiting if m.vehicles[s].state == LOST}
        if not back:
            return False
        if self.home:                 # sent home with the others, never back to work
            m.event(None, f"vehicle(s) {', '.join(map(str, back))} heard again after the "
                          "last re-plan left them out: brought home with the others",
                    back=back)
            return True
        outlook = self.outlook()
        if outlook["meets_requirement"]:
            return False
        m.event(None, f"vehicle(s) {', '.join(map(str, back))} heard again after the last "
                      "re-plan left them out: the plans in hand see "
                      f"{outlook['k_covered']} of {outlook['coverable']} coverable targets "
                      f"as required; re-planned with them", back=back)
        return True

    def outlook(self) -> dict:
        """`original_outlook` of every vehicle not lost, its later sorties included."""
        m, ctx = self.state.monitor, self.context()
        sysids = [s for s, v in sorted(m.vehicles.items()) if v.state != LOST]
        later = {s: np.vstack([points_xyz(ctx, [w for w in route.waypoints if w.snapshot])
                               for _, route in self.state.later.get(s, [])] or
                              [np.zeros((0, 3))]) for s in sysids}
        lost = len(m.vehicles) - len(sysids)
        return original_outlook(ctx, m, sysids, lost, later=later)
