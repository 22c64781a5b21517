"""Faults on demand: kill, link cuts, packet drop, refused arming.

Times of events (`@300s`) are seconds of mission time since the vehicle booted,
the clock that `--speedup` accelerates, so they line up with a planned flight.
Durations of link cuts (`+20s`) are wall-clock seconds, because what they test
is the ground station's loss detection, which runs on the wall clock.
"""

import random
import re
import threading
from dataclasses import dataclass, field

from common.errors import InputError

_KILL = re.compile(r"^(\d+)@(?:(\d+(?:\.\d*)?)s|item(\d+))$")
_CUT = re.compile(r"^(\d+)@(\d+(?:\.\d*)?)s\+(\d+(?:\.\d*)?)s$")


@dataclass
class FaultPlan:
    """The scripted faults of one vehicle."""
    kill_at_s: float | None = None       # mission time since boot
    kill_at_item: int | None = None      # when this mission item is reached (nav) or run (DO)
    cuts: list = field(default_factory=list)   # (start mission time s, duration wall s)
    refuse_arm: bool = False
    drain: float = 1.0                   # its battery empties this many times faster
    spool_s: float = 0.0                 # mission s on the ground after each takeoff is
                                         # commanded (motors spooling up, a slow start):
                                         # its liftoff comes that much after the command


def parse_kill(text: str) -> tuple:
    """``2@300s`` -> (2, 300.0, None); ``2@item12`` -> (2, None, 12). The number is a system id."""
    m = _KILL.match(text.strip())
    if not m:
        raise InputError("--kill", f"expected SYSID@SECONDSs or SYSID@itemN, got {text!r}")
    sysid = int(m.group(1))
    return sysid, (float(m.group(2)) if m.group(2) else None), (
        int(m.group(3)) if m.group(3) else None)


def parse_cut(text: str) -> tuple:
    """``3@100s+20s`` -> (3, 100.0, 20.0): system id, start (mission s), duration (wall s)."""
    m = _CUT.match(text.strip())
    if not m:
        raise InputError("--cut", f"expected SYSID@STARTs+DURATIONs, got {text!r}")
    return int(m.group(1)), float(m.group(2)), float(m.group(3))


class LinkFaults:
    """Per-link packet filter: random drop both ways, and cuts (nothing in, nothing out)."""

    def __init__(self, drop_pct: float = 0.0, seed: int = 0):
        self.drop_pct = drop_pct
        self._rng = random.Random(seed)
        self._cut_until = 0.0          # wall clock (time.monotonic)
        self.shadowed = False          # out of the radio's line of sight (the vehicle says)
        self._lock = threading.Lock()

    def cut(self, now: float, seconds: float) -> None:
        with self._lock:
            self._cut_until = max(self._cut_until, now + seconds)

    def is_cut(self, now: float) -> bool:
        return self.shadowed or now < self._cut_until

    def passes(self, now: float) -> bool:
        """Whether one packet gets through, in either direction."""
        if self.is_cut(now):
            return False
        with self._lock:
            return self.drop_pct <= 0 or self._rng.random() * 100.0 >= self.drop_pct
