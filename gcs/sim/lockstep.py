"""One clock for a simulated fleet: no vehicle's time runs ahead of the slowest.

Each simulated vehicle steps its own time in its own thread, as fast as its
speed-up asks and the machine allows. On a busy machine the threads are served
unevenly: at 100x beside two CPU hogs, three vehicles of one flight ran at 34x,
54x and 96x. Real vehicles share one clock, and a ground station counts a silent
vehicle's time at the pace of those it still hears, so vehicles whose clocks run
apart read as overdue in shadows they leave on time.

A `Lockstep` lets a vehicle step only as far as the slowest live member of its
fleet has stepped, plus a lead of a few ticks (so threads served in turn do not
stall each other): the fleet slows down together, as one world would.
"""

import threading


class Lockstep:
    """The fleet's members and how far each has stepped (world seconds: mission time
    since the member joined, counted from where the fleet stood then)."""

    def __init__(self):
        self._lock = threading.Lock()
        self._t = {}

    def join(self, member) -> None:
        """A member starts stepping (a vehicle booted): from the slowest member's time,
        so one that boots later is not held back by the time the others flew first."""
        with self._lock:
            if member not in self._t:
                self._t[member] = min(self._t.values(), default=0.0)

    def leave(self, member) -> None:
        """A member stops stepping (shot down, stopped): it holds nobody back."""
        with self._lock:
            self._t.pop(member, None)

    def allowed(self, member, lead_s: float) -> float:
        """Seconds ``member`` may step now: up to ``lead_s`` past the slowest other
        member (all it asks, alone or not a member)."""
        with self._lock:
            mine = self._t.get(member)
            others = [t for m, t in self._t.items() if m is not member]
        if mine is None or not others:
            return float("inf")
        return max(0.0, min(others) + lead_s - mine)

    def stepped(self, member, dt: float) -> None:
        with self._lock:
            if member in self._t:
                self._t[member] += dt
