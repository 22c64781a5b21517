"""What an autopilot does on its own when something goes wrong in flight, and which
of its settings keep the vehicle hidden (`Failsafe`, `FailsafeParameter`).

A proven mission is only as hidden as what the autopilot flies when a failsafe
fires: a plain RTL climbs and flies a straight line home, across the terrain and
into view of the posts. Each firmware's profile lists its failsafes that can fire
in flight (battery, ground-station link, RC, geofence, position), each with the
parameters that choose its action, in words that say where the vehicle would
fly, and the values whose flown path is proven hidden:

- a return along a path the plan proved: ArduPilot's SmartRTL (its own flown
  track back), PX4's mission-path return (RTL_TYPE 2 / 4);
- flying on with the mission (a link loss that changes nothing);
- a landing or a brake where it is: straight down under a hidden point stays
  below the exposure surface, but the vehicle is down away from its base. Such
  a value is a known risk (`FailsafeParameter.risks`), said plainly.

Nothing here talks to a vehicle: `gcs.flight.failsafes` reads, judges and sets
them, the simulator answers them (`gcs.sim.flavours`).
"""

from dataclasses import dataclass, field


@dataclass(frozen=True)
class FailsafeParameter:
    """One parameter that chooses what a failsafe does.

    ``actions``: value -> what the vehicle does, in words an operator reads (for a
    bitmask: bit number -> what that bit does). ``hidden``: the values whose
    flown path stays within the proof; ``safe``: the one `--set-failsafes`
    writes. A bitmask (``bits`` not 0) is hidden with those bits set, whatever
    the others, and is set by adding them. ``risks``: value -> what a hidden
    value still leaves to chance. ``source``: where the firmware defines it
    (each name, value and meaning was read there). ``off``: (parameter, test)
    pairs: when a test holds for that parameter's value, this failsafe cannot
    fire (FENCE_ENABLE 0), and any value of this one is hidden."""

    name: str
    actions: dict
    hidden: frozenset
    safe: float
    source: str
    bits: int = 0
    risks: dict = field(default_factory=dict)
    off: tuple = ()

    def is_hidden(self, value: float) -> bool:
        if self.bits:
            return int(value) & self.bits == self.bits
        return int(value) in self.hidden

    def safe_value(self, value: float | None) -> float:
        """The value to write in place of ``value`` (a bitmask keeps its other bits)."""
        if self.bits:
            return float(int(value or 0) | self.bits)
        return float(self.safe)

    def does(self, value: float) -> str:
        """What ``value`` makes the vehicle do, in words."""
        if self.bits:
            set_bits = [words for bit, words in sorted(self.actions.items())
                        if int(value) & (1 << bit)]
            missing = [self.actions[bit] for bit in range(32)
                       if self.bits & (1 << bit) and not int(value) & (1 << bit)]
            said = ", ".join(set_bits) if set_bits else "no option set"
            if missing:
                said += "; not set: " + ", ".join(missing)
            return said
        return self.actions.get(int(value), f"value {int(value)}, unknown to gcs (see the "
                                             "autopilot's manual): not proven hidden")

    def risk(self, value: float) -> str | None:
        """The known risk a value leaves (None: none)."""
        return None if self.bits else self.risks.get(int(value))


@dataclass(frozen=True)
class Failsafe:
    """One failsafe that can fire in flight: its name for people ("low battery"),
    the parameters that choose its action, and ``risk``: said whatever the values
    when no action of the firmware is hidden for certain."""

    name: str
    parameters: tuple               # of `FailsafeParameter`
    risk: str = ""


def parameter_names(failsafes) -> list:
    """Every parameter a profile's failsafes read (with those that turn one off),
    in order, each once."""
    names = []
    for failsafe in failsafes:
        for p in failsafe.parameters:
            for name in (p.name, *(gate for gate, _ in p.off)):
                if name not in names:
                    names.append(name)
    return names
