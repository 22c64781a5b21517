"""End-to-end fixtures: a plan per setting and k, planned once per session, and the
backends available here (see `fleets` for the settings and the backends)."""

from dataclasses import dataclass
from pathlib import Path

import pytest
from fleets import REAL, REAL_BACKENDS, SIM, Setting, make_plan, skip_unless_configured

from planner.context import PlanningContext
from planner.plan import Plan


@dataclass
class Planned:
    directory: Path
    plan: Plan
    ctx: object      # PlanningContext rebuilt from the directory (sensor model, targets)
    surface: object  # the plan's true exposure surface (outposts exactly as planned)


@pytest.fixture(scope="session")
def planned(tmp_path_factory):
    """``planned(k, backend)``: the Planned for ``backend`` (the simulator's or real
    SITL's setting, or a Setting) and k, planned once per session."""
    cache = {}

    def get(k: int = 0, backend="sim") -> Planned:
        setting = backend if isinstance(backend, Setting) else \
            (REAL if backend in REAL_BACKENDS else SIM)
        if (k, setting) not in cache:
            d = make_plan(tmp_path_factory.mktemp(f"plan_k{k}"), k, setting)
            plan = Plan.load(d)
            ctx = PlanningContext.load(d, plan)
            cache[k, setting] = Planned(d, plan, ctx, ctx.surface)
        return cache[k, setting]

    return get


# -- fleets --------------------------------------------------------------------------

@pytest.fixture(params=["sim", "ardupilot", "px4"])
def backend(request):
    """The name of a backend that is available here (real SITL skipped unless named)."""
    skip_unless_configured(request.param)
    return request.param




REAL_TIMEOUT_S = 1800


def pytest_collection_modifyitems(items):
    for item in items:
        callspec = getattr(item, "callspec", None)
        if callspec is not None and callspec.params.get("backend") in REAL_BACKENDS:
            item.add_marker(pytest.mark.timeout(REAL_TIMEOUT_S))
