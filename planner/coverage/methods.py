"""The coverage methods, registered behind one interface.

A method is a function ``(prep, params, progress) -> (routes, steps)``:
``prep`` is the prepared `CoverageProblem` (`problem.prepare`), ``routes`` one
list of viewpoint ids per UAV, ``steps`` the allocation trace (may be empty).
A module adds one with ``@register("name", "what it is")``; the names, in the
order users see them, are `planner.scenario.METHODS`.
"""

from dataclasses import dataclass
from typing import Callable

from planner.scenario import METHODS


@dataclass(frozen=True)
class Method:
    name: str
    summary: str
    run: Callable


REGISTRY: dict = {}


def register(name: str, summary: str):
    if name not in METHODS:
        raise ValueError(f"coverage method {name!r} is not in planner.scenario.METHODS")

    def add(run):
        REGISTRY[name] = Method(name, summary, run)
        return run
    return add


def method(name: str) -> Method:
    if name not in REGISTRY:
        raise ValueError(f"unknown coverage method {name!r}; choose one of "
                         f"{', '.join(REGISTRY)}")
    return REGISTRY[name]
