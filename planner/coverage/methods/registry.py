"""The coverage methods, registered behind one interface.

A method is a function ``(prep, params, progress) -> (routes, steps)``:
``prep`` is the prepared `CoverageProblem` (`model.prepared.prepare`),
``params`` its own settings (a dataclass it registers with), ``routes`` one
list of viewpoint ids per UAV, ``steps`` the allocation trace (may be empty).
A module of this package adds one with ``@register(...)``: the registry is the
one list of the methods (`planner.scenario.METHODS`, the command line's
choices and help are read from it).
"""

from dataclasses import dataclass, fields
from typing import Callable


@dataclass(frozen=True)
class Method:
    name: str          # as users give it: --method, plan.json
    summary: str       # what it is, in a sentence
    brief: str         # in the command line's help: "the paper's", "baseline"
    params: type       # its settings: a dataclass, every field with a default
    run: Callable
    order: int         # where users see it among the others

    def settings(self, given=None):
        """This method's params: ``given`` itself when it is one, else made from
        ``given`` (a dict of settings by name, None: the defaults), taking the
        entries its params have (the others are other methods' settings)."""
        if isinstance(given, self.params):
            return given
        given = dict(given or {})
        unknown = set(given) - every_setting()
        if unknown:
            raise ValueError(f"unknown coverage setting {', '.join(sorted(unknown))}; known: "
                             f"{', '.join(sorted(every_setting()))}")
        own = {f.name for f in fields(self.params)}
        return self.params(**{k: v for k, v in given.items() if k in own})


REGISTRY: dict = {}


def register(name: str, summary: str, brief: str, params: type, order: int):
    """Register the decorated function as coverage method ``name``."""
    def add(run):
        if name in REGISTRY:
            raise ValueError(f"coverage method {name!r} is registered twice")
        REGISTRY[name] = Method(name, summary, brief, params, run, order)
        return run
    return add


def method(name: str) -> Method:
    if name not in REGISTRY:
        raise ValueError(f"unknown coverage method {name!r}; choose one of "
                         f"{', '.join(names())}")
    return REGISTRY[name]


def names() -> tuple:
    """The methods' names, in the order users see them."""
    return tuple(sorted(REGISTRY, key=lambda n: REGISTRY[n].order))


def every_setting() -> set:
    """The settings some method takes (a name none takes is a mistake)."""
    return {f.name for m in REGISTRY.values() for f in fields(m.params)}
