"""Pure computation: terrain in, hidden reduced-time coverage routes out."""

import hashlib
import os
import re
from pathlib import Path


def _kernel_cache_dir() -> Path:
    """Where numba keeps the compiled kernels: one folder per version of the
    kernels' sources. numba re-compiles a cached kernel when its own file
    changes, not when a function it inlines from another file does: after a fix
    to `exposure.los.next_patch`, `exposure.kernels.points_hidden` ran the old
    walk from its cache until the cache was deleted. So the folder is keyed by
    every file that uses numba and every planner file those import (a constant
    is frozen into a kernel when it compiles), and by no other: a docstring
    edit elsewhere cost the next plan a full recompile (80 s on 2 cores)."""
    home = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return home / "gcs-planner" / "kernels" / kernel_digest(Path(__file__).parent)


def kernel_digest(root: Path) -> str:
    """The kernel cache's key for the package at ``root`` (`_kernel_cache_dir`)."""
    root = root.resolve()
    sources = {path: path.read_bytes() for path in root.rglob("*.py")}
    keyed = _imported_closure(root, sources, [p for p, text in sources.items()
                                              if b"numba" in text])
    digest = hashlib.sha256()
    for path in sorted(keyed):
        digest.update(str(path.relative_to(root)).encode() + b"\0" + sources[path])
    return digest.hexdigest()[:16]


#: ``from planner.x.y import`` / ``from ..x import`` / ``from . import x``: the module
#: part of a planner import (a plain ``import planner.x`` is not used by the kernels)
_IMPORT = re.compile(rb"^\s*from\s+(planner(?:\.\w+)*|\.+\w*(?:\.\w+)*)\s+import\s+([\w, ()]+)",
                     re.MULTILINE)


def _imported_closure(root: Path, sources: dict, start: list) -> set:
    """``start`` and every planner source file they import, transitively."""
    seen, todo = set(), list(start)
    while todo:
        path = todo.pop()
        if path in seen:
            continue
        seen.add(path)
        for module, names in _IMPORT.findall(sources[path]):
            todo += [p for p in _module_files(root, path, module.decode(), names.decode())
                     if p in sources]
    return seen


def _module_files(root: Path, importer: Path, module: str, names: str) -> list:
    """The files an import statement of ``importer`` may read: the module (or
    package ``__init__``) and, for ``from package import name``, the submodule."""
    if module.startswith("planner"):
        base = root.joinpath(*module.split(".")[1:])
    else:                                   # relative: one dot is the importer's package
        rest = module.lstrip(".")
        up = [".."] * (len(module) - len(rest) - 1)
        base = importer.parent.joinpath(*up, *filter(None, rest.split(".")))
    base = base.resolve()
    found = [base.with_suffix(".py"), base / "__init__.py"]
    # "from . import kernels as K" reads kernels.py
    found += [base / f"{name.strip(' ()').split()[0]}.py" for name in names.split(",")
              if name.strip(' ()')]
    return found


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
