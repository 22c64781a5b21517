"""Where an uploaded mission comes from, and what it is proven against.

A mission reaches a vehicle only as a `missions.check.CheckedMission`. Its
source is either a plan directory (each route's mission built for a firmware)
or a mission file (``.plan``, ``.waypoints``), which is checked against the
plan it came from: the ``plan.json`` beside it, or the plan directory given
(``--plan DIR``). Sources are read and checked here, before any vehicle is
contacted: a bad file is an `InputError` naming it.

A file with no plan (or a plan without its ``terrain.tif``) has nothing to
prove its legs against; it is refused unless the caller allows it
(``--unchecked``), and then passes the structure check only, with a note
saying what was not proven.
"""

from dataclasses import dataclass, field
from pathlib import Path

from autopilots import NAMES
from common.errors import InputError
from planner.plan import PLAN_FILE, TERRAIN_FILE

from .build import MissionOptions, VehicleMission, firmware_profile, vehicle_mission
from .check import checked, unproven

MISSION_SUFFIXES = (".plan", ".waypoints", ".txt")


def saved_plan_surface(directory, plan):
    """The exposure surface a saved plan was made against (``terrain.tif``, the
    plan's outposts, parameters and lowest seen altitudes). Every check of a
    saved plan's missions gets its surface here (`planner.context.load_surface`)."""
    directory = Path(directory)
    if not (directory / TERRAIN_FILE).is_file():
        raise InputError(directory / TERRAIN_FILE, "missing: the legs cannot be proven "
                                                   "hidden and clear without the plan's terrain")
    from planner.context import load_surface

    return load_surface(directory, plan)


@dataclass
class Proof:
    """What a source's missions are checked against: a plan's surface, or nothing
    (``surface`` None: ``reason`` says why; allowed only when ``unchecked``)."""

    surface: object = None
    clearance_m: float | None = None
    reason: str | None = None
    plan_dir: Path | None = None
    speed_mps: float | None = None      # the plan's: its schedule is timed at it

    def check(self, mission, name):
        if self.surface is not None:
            return checked(mission, self.surface, self.clearance_m, name=name,
                           speed_mps=self.speed_mps)
        return unproven(mission, self.reason, name=name)


@dataclass
class MissionSource:
    """One uploadable route: its mission for each firmware, checked on demand."""

    id: int
    source: str                 # a file, or "DIR vehicle N"
    missions: dict              # firmware -> VehicleMission, or the InputError building it
    proof: Proof
    expected: str | None        # the firmware it is meant for (None: any)
    bound: str | None = None    # a file's own firmware: it is for vehicles of that one only
    _checked: dict = field(default_factory=dict)

    def checked(self, firmware: str, vehicle=None):
        """The `CheckedMission` for ``firmware``; InputError naming the source if the
        mission cannot be built or fails the check, or if it is a file written for
        another firmware (``vehicle``: the system id named in that message)."""
        if self.bound is not None and firmware != self.bound:
            raise InputError(self.source, firmware_mismatch(self.bound, firmware, vehicle))
        if firmware not in self._checked:
            try:
                built = self.missions[firmware]
                if isinstance(built, InputError):
                    raise built
                self._checked[firmware] = self.proof.check(built, self.source)
            except InputError as exc:
                self._checked[firmware] = exc
        result = self._checked[firmware]
        if isinstance(result, InputError):
            raise result
        return result

    def check_now(self) -> None:
        """Check for the expected firmware (each firmware when none is): before any
        connection. InputError on the first failure."""
        for firmware in [self.expected] if self.expected else NAMES:
            self.checked(firmware)

    @property
    def unproven_note(self) -> str | None:
        return self.proof.reason and f"{self.source}: unchecked: legs not proven hidden " \
                                     f"from outposts nor clear of the terrain ({self.proof.reason})"


class _Plans:
    """Plans and their surfaces, each loaded once."""

    def __init__(self, unchecked: bool):
        self.unchecked = unchecked
        self._proofs = {}

    def proof(self, directory: Path | None, what: str) -> tuple:
        """(plan or None, Proof) for a source whose plan directory is ``directory``."""
        from planner.plan import Plan

        if directory is None:
            return None, self._without(f"no {PLAN_FILE} beside it and no --plan", what)
        key = directory.resolve()
        if key not in self._proofs:
            plan = Plan.load(directory)
            if not (directory / TERRAIN_FILE).is_file():
                if not self.unchecked:
                    raise InputError(directory / TERRAIN_FILE, "missing: the legs cannot be "
                                     "proven hidden and clear without the plan's terrain "
                                     "(--unchecked uploads them unproven)")
                proof = self._without(f"no {TERRAIN_FILE} in {directory}", what)
            else:
                proof = Proof(saved_plan_surface(directory, plan), plan.params.get("clearance_m"),
                              plan_dir=directory, speed_mps=plan.params.get("speed_mps"))
            self._proofs[key] = (plan, proof)
        return self._proofs[key]

    def _without(self, reason: str, what: str) -> Proof:
        if not self.unchecked:
            raise InputError(what, f"nothing to check it against ({reason}); give the plan "
                                   "it came from with --plan DIR, or --unchecked to upload "
                                   "it unproven")
        return Proof(reason=reason)


def load_sources(sources, plan_dir=None, unchecked: bool = False,
                 firmware: str | None = None) -> list:
    """`MissionSource` per route of one plan directory, or per mission file (one
    route each), every one checked for its firmware now; InputError on the first
    bad one. ``firmware``: the firmware every mission is for (None: each source's
    own: the file's firmwareType, the plan's firmware)."""
    plans = _Plans(unchecked)
    paths = [Path(s) for s in sources]
    dirs = [p for p in paths if p.is_dir()]
    if firmware is not None:
        firmware = firmware_profile(firmware).name
    if dirs:
        if len(paths) > 1:
            raise InputError(dirs[0], "give one plan directory, or mission files, not both")
        if not (dirs[0] / PLAN_FILE).is_file():
            raise InputError(dirs[0], f"not a plan directory (no {PLAN_FILE})")
        out = _plan_sources(dirs[0], plans, firmware)
    else:
        given = Path(plan_dir) if plan_dir is not None else None
        if given is not None and not (given / PLAN_FILE).is_file():
            raise InputError(given, f"--plan: not a plan directory (no {PLAN_FILE})")
        out = []
        for number, path in enumerate(paths, start=1):
            out.append(_file_source(path, number, len(paths), given, plans, firmware))
        if len({s.id for s in out}) != len(out):
            for n, s in enumerate(out, start=1):
                s.id = n
    for s in out:
        s.check_now()
    return out


def _plan_sources(directory: Path, plans: _Plans, firmware) -> list:
    plan, proof = plans.proof(directory, str(directory))
    options = MissionOptions(speed_mps=plan.params.get("speed_mps"))
    out = []
    for route in plan.vehicles:
        if not route.waypoints:
            continue
        if len(route.sorties) > 1:
            raise InputError(directory, f"vehicle {route.id} flies {len(route.sorties)} "
                                        "sorties, one battery each: upload one sortie's "
                                        f"mission at a time (vehicle-{route.id}-sortie-1.plan, "
                                        "...) once the vehicle is on the ground at its base")
        missions = {fw: vehicle_mission(route, fw, options) for fw in NAMES}
        out.append(MissionSource(route.id, f"{directory} vehicle {route.id}", missions, proof,
                                 firmware or plan.params.get("firmware")))
    if not out:
        raise InputError(directory, "the plan has no route with waypoints")
    return out


def _file_source(path: Path, number: int, count: int, plan_dir, plans: _Plans,
                 firmware) -> MissionSource:
    import re

    suffix = path.suffix.lower()
    if suffix not in MISSION_SUFFIXES:
        raise InputError(path, "not a mission file: expected .plan or .waypoints")
    if not path.is_file():
        raise InputError(path, "no such file")
    match = re.search(r"(\d+)(?:-sortie-(\d+))?$", path.stem)
    route_id = int(match.group(1)) if match and count > 1 else number
    directory = plan_dir if plan_dir is not None else \
        (path.parent if (path.parent / PLAN_FILE).is_file() else None)
    plan, proof = plans.proof(directory, str(path))
    missions, own = _file_missions(path, route_id)
    if own is not None and firmware is not None and firmware != own:
        raise InputError(path, firmware_mismatch(own, firmware))
    expected = firmware or own or (plan.params.get("firmware") if plan is not None else None)
    return MissionSource(route_id, str(path), missions, proof, expected, bound=own)


def firmware_mismatch(own: str, wanted: str, vehicle=None) -> str:
    """Why a mission file of firmware ``own`` is not given to a ``wanted`` vehicle:
    its items are that firmware's (camera commands, home item), and reading them
    as another's would fly something nobody planned."""
    from autopilots import profile

    a, b = profile(own), profile(wanted)
    who = f"vehicle {vehicle} runs {b.title}" if vehicle is not None else \
        f"--firmware is {b.name}"
    return (f"{_article(a.title)} {a.title} mission, and {who}: write {_article(b.title)} "
            f"{b.title} one from its plan with `gcs export PLAN_DIR --firmware {b.name}`")


def _article(word: str) -> str:
    return "an" if word[:1].lower() in "aeiou" else "a"


def mission_file_firmware(path) -> str | None:
    """The firmware a mission file says it is for: a ``.plan``'s ``firmwareType``,
    a ``.waypoints`` file's mark (`missions.wpl.marked_firmware`), else its camera
    commands; None when it says nothing. InputError for a file that cannot be read."""
    path = Path(path)
    if path.suffix.lower() == ".plan":
        from .qgc import load_plan_file

        return load_plan_file(path).declared
    from .wpl import read_waypoints

    return _waypoints_firmware(read_waypoints(path))


def _file_missions(path: Path, route_id: int) -> tuple:
    """({firmware: VehicleMission}, the file's own firmware or None), read now."""
    if path.suffix.lower() == ".plan":
        from .qgc import load_plan_file

        own = load_plan_file(path).declared          # InputError for a bad file
        missions = {}
        for fw in NAMES:
            try:
                items = load_plan_file(path, fw).items
                missions[fw] = VehicleMission(route_id, fw, items, [None] * len(items))
            except InputError as exc:
                missions[fw] = exc
        return missions, own
    from .wpl import mission_items, read_waypoints

    lines = read_waypoints(path)                     # InputError for a bad file
    missions = {}
    for fw in NAMES:                                 # line 0 is home: kept or dropped per firmware
        try:
            items = mission_items(lines, fw, path)
            missions[fw] = VehicleMission(route_id, fw, items, [None] * len(items))
        except InputError as exc:
            missions[fw] = exc
    return missions, _waypoints_firmware(lines)


def _waypoints_firmware(lines) -> str | None:
    """The firmware a ``.waypoints`` file's lines are for: the mark on its home line
    (every file gcs writes has one), else for a file without it (another program's,
    or ours from before the mark) the firmware whose camera commands it uses, else
    None: such a file goes to a vehicle of either firmware."""
    from .wpl import marked_firmware

    return marked_firmware(lines) or _camera_firmware(lines)


def _camera_firmware(items) -> str | None:
    """The firmware whose camera command a ``.waypoints`` file uses, None without
    camera commands (or with both firmwares')."""
    from autopilots import profile

    commands = {int(it.command) for it in items}
    found = [fw for fw in NAMES if profile(fw).camera_command in commands]
    return found[0] if len(found) == 1 else None
