"""Copies of a saved plan for tests that export or edit one (a module of its own:
test modules cannot import from conftest, which sitl_tests has one of too)."""

import shutil

from planner.plan import PLAN_FILE, TERRAIN_FILE


def copy_plan(planned, folder):
    """``folder`` made a copy of the session plan (plan.json, terrain.tif: no mission
    files), to export or edit."""
    folder.mkdir()
    for name in (PLAN_FILE, TERRAIN_FILE):
        shutil.copy(planned.dir / name, folder / name)
    return folder
