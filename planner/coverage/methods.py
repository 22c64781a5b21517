"""The coverage methods, registered behind one interface.

A method is a function ``(prep, params, progress) -> (routes, steps)``:
``prep`` is the prepared `CoverageProblem` (`problem.prepare`), ``routes`` one
list of viewpoint ids per UAV, ``steps`` the allocation trace (may be empty).
A module adds one with ``@register("name", "what it is")``; `METHODS` lists
them in registration order, which is the order `solve` documents and the CLI
offers.
"""

from dataclasses import dataclass
from typing import Callable


@dataclass(frozen=True)
class Method:
    name: str
    summary: str
    run: Callable


REGISTRY: dict = {}


def register(name: str, summary: str):
    def add(run):
        REGISTRY[name] = Method(name, summary, run)
        return run
    return add


def method(name: str) -> Method:
    if name not in REGISTRY:
        raise ValueError(f"unknown coverage method {name!r}; choose one of "
                         f"{', '.join(REGISTRY)}")
    return REGISTRY[name]
