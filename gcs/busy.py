"""The ground station's busy spells: wall time its flight loop spends computing.

A re-plan, a sortie's upload or a segment switch holds the flight loop (and with
it the separation guard and the battery watch) for a second or a few. Flying at
1x that is a second or a few of flight. A simulator sped up 100 times would turn
it into minutes of unwatched flight that no real flight has, so a simulator in
the same process (`gcs.sim.vehicle`) asks `busy_now()` and runs at real time
through a spell, as the real world would; one in another process cannot ask and
keeps its speed-up. Nothing here changes what the ground station does.
"""

import threading
import time
from contextlib import contextmanager

_lock = threading.Lock()
_open = 0                 # spells open now (uploads run on several threads at once)
_since = None             # monotonic time the current spell began
_total_s = 0.0            # wall seconds of spells so far, in this process
_ended = -float("inf")    # monotonic time the last spell ended


@contextmanager
def busy():
    """A span of the flight loop's work that blocks its watching."""
    global _open, _since, _total_s, _ended
    with _lock:
        if _open == 0:
            _since = time.monotonic()
        _open += 1
    try:
        yield
    finally:
        with _lock:
            _open -= 1
            if _open == 0:
                _ended = time.monotonic()
                _total_s += _ended - _since
                _since = None


def busy_now() -> bool:
    """True while a spell is open."""
    return _open > 0


def busy_total_s() -> float:
    """Wall seconds the ground station has been busy in this process, the open
    spell's so far included."""
    with _lock:
        return _total_s + (time.monotonic() - _since if _since is not None else 0.0)


def last_end() -> float:
    """Monotonic time the last spell ended: now while one is open, -inf before any."""
    with _lock:
        return time.monotonic() if _open else _ended
