"""The simulated battery: a pack of so many minutes of hovering, drawn faster while
climbing, put in full by the crew on the ground; its low-battery failsafes fire at
the levels and with the actions the firmware's parameters name, as ArduPilot's
(BATT_LOW_MAH / BATT_CRT_MAH of BATT_CAPACITY, BATT_FS_LOW_ACT / BATT_FS_CRT_ACT)
and PX4's (BAT_CRIT_THR / BAT_EMERGEN_THR, COM_LOW_BAT_ACT) do.
"""

from dataclasses import dataclass, field

#: the pack's capacity (mAh): BATT_CAPACITY of the ArduPilot flavour, what
#: BATTERY_STATUS counts drawn charge in
CAPACITY_MAH = 5000

#: extra draw per m/s of climb, as a share of the hover draw: a climb at v lifts the
#: weight, m g v more power; a 1.5 kg quadcopter hovering on about 180 W climbs at
#: 1 m/s on 15 W more (8 %). Descents are counted at the hover draw.
CLIMB_DRAW_PER_MPS = 0.08

#: what each ArduPilot failsafe action value does: a mode to switch to ("A or B":
#: B where A is refused, as SmartRTL is once its buffer is full), "fall" (motors
#: off) or None (a warning only). 6 (DO_LAND_START) falls back to RTL in a mission
#: without one; 7 brakes, then lands (ArduCopter/events.cpp do_failsafe_action).
ARDUPILOT_ACTIONS = {0: None, 1: "LAND", 2: "RTL", 3: "SMART_RTL or RTL",
                     4: "SMART_RTL or LAND", 5: "fall", 6: "RTL", 7: "LAND"}


@dataclass
class Failsafe:
    """One level: below ``pct`` remaining, ``action`` (mode, "fall" or None)."""
    name: str
    pct: float
    action: str | None


@dataclass
class Battery:
    capacity_s: float                   # hover seconds from full to empty
    drain: float = 1.0                  # a fault: it empties this many times faster
    used_s: float = 0.0                 # hover seconds drawn from this pack
    fired: set = field(default_factory=set)   # failsafe levels fired on this pack

    @property
    def remaining_pct(self) -> float:
        return max(0.0, 100.0 * (1.0 - self.used_s / self.capacity_s))

    @property
    def used_fraction(self) -> float:
        return self.used_s / self.capacity_s

    def draw(self, dt: float, climb_mps: float) -> None:
        self.used_s += dt * self.drain * (1.0 + CLIMB_DRAW_PER_MPS * max(0.0, climb_mps))

    def swap(self) -> None:
        self.used_s, self.fired = 0.0, set()

    def due(self, levels) -> list:
        """The failsafes of ``levels`` the charge has fallen below and that have not
        fired on this pack yet (each fires once), marked fired."""
        out = [f for f in levels if f.name not in self.fired and self.remaining_pct < f.pct]
        self.fired |= {f.name for f in out}
        return out


def ardupilot_levels(params: dict) -> list:
    """ArduPilot's battery failsafes, low then critical: each a level of remaining
    capacity (mAh of BATT_CAPACITY; 0, its default, turns it off) and its action."""
    capacity, out = params.get("BATT_CAPACITY", 0.0), []
    for name, mah, act in (("low", "BATT_LOW_MAH", "BATT_FS_LOW_ACT"),
                           ("critical", "BATT_CRT_MAH", "BATT_FS_CRT_ACT")):
        if capacity > 0 and params.get(mah, 0.0) > 0:
            out.append(Failsafe(name, 100.0 * params[mah] / capacity,
                                ARDUPILOT_ACTIONS.get(int(params.get(act, 0)))))
    return out


def px4_levels(params: dict) -> list:
    """PX4's battery failsafes at its critical and emergency levels (fractions
    remaining), as COM_LOW_BAT_ACT says: 2 lands at both, 3 returns at the critical
    level and lands at the emergency one, 0 warns."""
    act = int(params.get("COM_LOW_BAT_ACT", 0))
    critical = {2: "AUTO.LAND", 3: "AUTO.RTL"}.get(act)
    emergency = "AUTO.LAND" if act in (2, 3) else None
    return [Failsafe("critical", 100.0 * params.get("BAT_CRIT_THR", 0.07), critical),
            Failsafe("emergency", 100.0 * params.get("BAT_EMERGEN_THR", 0.05), emergency)]
