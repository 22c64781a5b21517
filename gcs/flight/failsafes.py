"""Every failsafe of a vehicle, read before arming, judged against its firmware's
profile (`autopilots.failsafe`), and made hidden when the operator says so.

- `read`: each failsafe parameter of the profile, as the vehicle holds it (a
  `Setting` each: its value, what it does, whether its flown path is proven);
- `refusal`: the words that refuse a vehicle whose failsafe would leave the proof;
- `make_hidden`: writes the hidden-safe values of the settings that are not,
  reads each back (a vehicle that keeps another value is refused), and returns
  what it changed, so that `restore` can put the previous values back;
- `risks`: what stays a risk with the hidden values (a landing away from the
  base), said in the preflight and in the report;
- `buffer_risks`: where a route outgrows the vehicle's own SmartRTL buffer
  (`planner.returns`): from there a failsafe's SmartRTL is gone.
"""

from dataclasses import dataclass

from autopilots.failsafe import parameter_names
from gcs import params
from planner.returns import smartrtl_budget

#: writes of one failsafe parameter, each read back, before it is refused
SET_ATTEMPTS = 3

#: how to fix a refusal, said with it
FIX = ("add --set-failsafes to this gcs fly command: it writes the hidden-safe values, "
       "reads them back and keeps the previous ones in flight.json for "
       "`gcs failsafes --restore FLIGHT_DIR`")


class FailsafeError(Exception):
    """A vehicle's failsafes could not be read, set or restored as asked."""


@dataclass
class Setting:
    """One failsafe parameter of one vehicle, as read."""

    failsafe: str                   # the failsafe's name for people
    parameter: object               # `autopilots.failsafe.FailsafeParameter`
    value: float | None             # None: not answered
    kind: int | None                # MAV_PARAM_TYPE it came in
    off: bool = False               # the failsafe cannot fire (FENCE_ENABLE 0)

    @property
    def name(self) -> str:
        return self.parameter.name

    @property
    def hidden(self) -> bool:
        return self.off or (self.value is not None and self.parameter.is_hidden(self.value))

    @property
    def risk(self) -> str | None:
        if self.off or self.value is None or not self.hidden:
            return None
        return self.parameter.risk(self.value)

    @property
    def to_set(self) -> bool:
        """What --set-failsafes writes: a value out of the proof, and a hidden one that
        leaves a known risk its firmware's chosen value does not share (a low battery
        that only warns: the vehicle flies on toward an empty pack)."""
        if not self.hidden:
            return True
        p = self.parameter
        return self.risk is not None and not p.bits and int(self.value) != int(p.safe) \
            and p.risk(p.safe) != self.risk

    def said(self) -> str:
        if self.value is None:
            return f"{self.name} not answered (what the {self.failsafe} failsafe does is unknown)"
        off = " (it cannot fire: " + ", ".join(g for g, _ in self.parameter.off) + " off)" \
            if self.off else ""
        return f"{self.name} = {self.value:g}, {self.parameter.does(self.value)}{off}"

    def report(self) -> dict:
        return {"failsafe": self.failsafe, "parameter": self.name, "value": self.value,
                "does": None if self.value is None else self.parameter.does(self.value),
                "hidden": self.hidden, "off": self.off, "risk": self.risk,
                "source": self.parameter.source}


def read(link, profile) -> list:
    """Every failsafe parameter of ``profile`` as the vehicle on ``link`` holds it."""
    values = params.read_many(link, parameter_names(profile.failsafes))
    out = []
    for failsafe in profile.failsafes:
        for p in failsafe.parameters:
            got = values[p.name]
            off = any(values[gate] is not None and test(values[gate].value)
                      for gate, test in p.off)
            out.append(Setting(failsafe.name, p, None if got is None else got.value,
                               None if got is None else got.kind, off))
    return out


def unproven(settings) -> list:
    return [s for s in settings if not s.hidden]


def refusal(settings) -> str:
    """Why a vehicle is refused: each failsafe that would fly out of the proof."""
    return "; ".join(
        f"{s.failsafe}: {s.said()}: " + ("not proven hidden" if s.value is None else
                                         "what it would fly there is in view of the posts")
        for s in unproven(settings))


def by_vehicles(said: dict) -> str:
    """{sysid: text} said once per text: "vehicles 1, 3: ...; vehicle 2: ..."."""
    groups = {}
    for sysid, text in sorted(said.items()):
        groups.setdefault(text, []).append(sysid)
    return "; ".join(("vehicles " if len(ids) > 1 else "vehicle ")
                     + ", ".join(map(str, ids)) + f": {text}" for text, ids in groups.items())


def risks(profile, settings) -> list:
    """What stays a known risk with these settings, one line each: the firmware's
    failsafes with no hidden action at all, and the hidden values' own risks."""
    out = [f"{f.name}: {f.risk}" for f in profile.failsafes if f.risk]
    out += [f"{s.failsafe}: {s.name} = {s.value:g}: {s.risk}" for s in settings if s.risk]
    return out


def make_hidden(link, settings) -> list:
    """Write the hidden-safe value of each setting `Setting.to_set` names, and read
    it back; [{parameter, previous, value, type}] of what was changed. FailsafeError
    when one is not answered or reads back otherwise (the changes made so far are
    in the error's ``changes``)."""
    changes = []
    for s in [s for s in settings if s.to_set]:
        if s.value is None:
            raise _error(link, f"{s.name} not answered: cannot be set", changes)
        value = s.parameter.safe_value(s.value)
        back = _set(link, s, value)
        if back is not None and back.value == value:
            changes.append({"parameter": s.name, "previous": s.value, "value": value,
                            "type": s.kind})
            continue
        got = "no answer" if back is None else f"{back.value:g}"
        raise _error(link, f"{s.name} set to {value:g} reads back as {got} "
                           f"({SET_ATTEMPTS} attempts)", changes)
    return changes


def _set(link, setting, value):
    """Write ``value`` and read it back, again while the read-back differs; the last
    read-back. The read-back is the judge: at 20 % loss a write's echo was lost
    while the value was set ("19 reads back as 19"), and a late answer to an
    earlier read once stood for the write ("5 reads back as 1")."""
    back = None
    for _ in range(SET_ATTEMPTS):
        params.write(link, setting.name, value, setting.kind)
        back = params.read(link, setting.name)
        if back is not None and back.value == value:
            break
    return back


def restore(link, changes) -> list:
    """Put each changed parameter back to its previous value; the names that read
    back otherwise (empty: all restored)."""
    failed = []
    for change in changes:
        name, previous = change["parameter"], float(change["previous"])
        params.write(link, name, previous, int(change["type"]))
        back = params.read(link, name)
        if back is None or back.value != previous:
            failed.append(name)
    return failed


def _error(link, problem: str, changes) -> FailsafeError:
    error = FailsafeError(f"vehicle {link.sysid}: {problem}")
    error.changes = changes
    return error



def buffer_risks(link, profile, route) -> list:
    """Where ``route`` outgrows the SmartRTL buffer the vehicle holds (its own
    SRTL_POINTS and SRTL_ACCURACY), one line per sortie; [] for a firmware whose
    return is not its own track, or a route that fits."""
    srtl = profile.smartrtl
    if srtl is None or route is None:
        return []
    read = params.read_many(link, [srtl.points_param, srtl.accuracy_param])
    points, accuracy = read[srtl.points_param], read[srtl.accuracy_param]
    if points is None or accuracy is None:
        return [f"SmartRTL buffer: {srtl.points_param} / {srtl.accuracy_param} not answered: "
                "whether a failsafe's SmartRTL holds its whole path is unknown"]
    held = min(int(points.value), srtl.points_max)
    return [f"SmartRTL buffer: {srtl.points_param} = {held} holds less than sortie "
            f"{s['sortie']} of route {route.id} needs (about {s['points']} points at "
            f"{srtl.accuracy_param} {accuracy.value:g}): full at its waypoint {s['full_at']}, "
            "past which a failsafe's SmartRTL is gone and it takes its fallback (LAND where "
            "it is)"
            for s in smartrtl_budget(route, held, accuracy.value) if s["full_at"] is not None]
