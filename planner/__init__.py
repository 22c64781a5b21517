"""Pure computation: terrain in, hidden reduced-time coverage routes out."""

import hashlib
import os
from pathlib import Path


def _kernel_cache_dir() -> Path:
    """Where numba keeps the compiled kernels: one folder per version of the
    package's sources. numba re-compiles a cached kernel when its own file
    changes, not when a function it inlines from another file does: after a fix
    to `exposure.los.next_patch`, `exposure.kernels.points_hidden` ran the old
    walk from its cache until the cache was deleted."""
    digest = hashlib.sha256()
    for path in sorted(Path(__file__).parent.rglob("*.py")):
        digest.update(path.read_bytes())
    home = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return home / "gcs-planner" / "kernels" / digest.hexdigest()[:16]


# Set before numba is imported (it reads the variable then); a folder given by the
# user, or by the process that started this one, is kept. numba falls back to
# __pycache__ where this folder cannot be written.
os.environ.setdefault("NUMBA_CACHE_DIR", str(_kernel_cache_dir()))
# The parallel kernels' OpenMP threads wait for their next task asleep, not
# spinning: the ground station runs its flight loop, its links and (simulated)
# vehicles as threads beside the kernels, and a spinning wait took the cores they
# needed (a one-point parallel call cost 6-12 ms on a busy 2-core machine, 0.1 ms
# with this). Set before numba's OpenMP layer starts; the user's setting is kept.
os.environ.setdefault("OMP_WAIT_POLICY", "passive")


def kernels_compiled() -> bool:
    """Whether numba's cache holds compiled kernels for these sources (False before
    the first plan after an install or a change: that plan compiles them). True
    where that folder cannot be written: numba keeps them beside the sources then,
    out of this function's sight, and nothing is claimed."""
    folder = Path(os.environ["NUMBA_CACHE_DIR"])
    if any(folder.rglob("*.nbi")):
        return True
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError:
        return True
    return not os.access(folder, os.W_OK)
