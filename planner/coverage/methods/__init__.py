"""The coverage methods: one module each, registering itself (`registry.register`).

A new method is one module here: its settings (a dataclass), what it is, and
its ``run``; it is found by its file. A method imports its search code
(`planner.coverage.search`) when it runs, so that this package stays light:
the command line reads the methods' names and help from it without loading
numba.
"""

from importlib import import_module
from pkgutil import iter_modules

from .registry import REGISTRY, Method, method, names, register

for _module in iter_modules(__path__):
    if _module.name != "registry":
        import_module(f"{__name__}.{_module.name}")

#: the methods' names, in the order users see them
METHODS = names()

__all__ = ["METHODS", "REGISTRY", "Method", "method", "names", "register"]
