"""Every failsafe keeps the vehicle hidden (issue 60).

The profiles' failsafe parameters are judged against the firmwares' own sources
(ArduPilot 4.7 at /opt/ardupilot, PX4 1.17 at /opt/px4: each value's meaning as
the parameter's documentation there says it; skipped where absent); the
preflight against the simulated vehicles, by what they hold afterwards and by
their own tracks (nothing armed when refused)."""

import json
import re
from pathlib import Path

import pytest
from sim_fleet import quick_fleet

from autopilots import profile
from gcs.cli import main
from gcs.sim import read_track, track_path
from gcs.sim.flavours import flavour

pytestmark = pytest.mark.timeout(180)

ARDUPILOT_SRC = Path("/opt/ardupilot")
PX4_SRC = Path("/opt/px4")


# -- the profiles, against the firmwares' sources -----------------------------------------
def _ardupilot_doc(file: str, param: str) -> str:
    """The documentation block of ArduPilot parameter ``param`` (its @Param: name
    inside the group) in ``file``."""
    text = (ARDUPILOT_SRC / file).read_text()
    found = re.search(rf"// @Param: {param}\n(.*?)AP_GROUPINFO|// @Param: {param}\n(.*?)"
                      r"GSCALAR", text, re.S)
    assert found, f"{param} not documented in {file}"
    return found.group(1) or found.group(2)


def _ardupilot_values(doc: str, tag: str = "Values") -> dict:
    line = re.search(rf"// @{tag}(?:{{Copter[^}}]*}})?: (.*)", doc).group(1)
    return {int(k): v.strip() for k, v in (item.split(":", 1) for item in line.split(","))}


ARDUPILOT_PARAMS = {      # profile name -> (file, name in its group)
    "BATT_FS_LOW_ACT": ("libraries/AP_BattMonitor/AP_BattMonitor_Params.cpp", "FS_LOW_ACT"),
    "BATT_FS_CRT_ACT": ("libraries/AP_BattMonitor/AP_BattMonitor_Params.cpp", "FS_CRT_ACT"),
    "FS_GCS_ENABLE": ("ArduCopter/Parameters.cpp", "FS_GCS_ENABLE"),
    "FS_THR_ENABLE": ("ArduCopter/Parameters.cpp", "FS_THR_ENABLE"),
    "FS_EKF_ACTION": ("ArduCopter/Parameters.cpp", "FS_EKF_ACTION"),
    "FENCE_ACTION": ("libraries/AC_Fence/AC_Fence.cpp", "ACTION"),
}
#: the hidden-safe value's meaning, as the firmware's documentation names it
ARDUPILOT_SAFE = {"BATT_FS_LOW_ACT": "SmartRTL or Land", "BATT_FS_CRT_ACT": "Land",
                  "FS_GCS_ENABLE": "SmartRTL or Land", "FS_THR_ENABLE": "SmartRTL or Land",
                  "FS_EKF_ACTION": "Land", "FENCE_ACTION": "SmartRTL or Land"}


def _parameters(firmware):
    return {p.name: p for f in profile(firmware).failsafes for p in f.parameters}


@pytest.mark.skipif(not ARDUPILOT_SRC.is_dir(), reason="no ArduPilot sources at /opt/ardupilot")
def test_ardupilot_failsafes_are_the_firmware_s_own():
    params = _parameters("ardupilot")
    assert set(ARDUPILOT_PARAMS) | {"FS_OPTIONS"} == set(params)
    for name, (file, local) in ARDUPILOT_PARAMS.items():
        values = _ardupilot_values(_ardupilot_doc(file, local))
        assert set(params[name].actions) == set(values), name
        safe = int(params[name].safe)
        assert re.fullmatch(rf"(Enabled always )?{ARDUPILOT_SAFE[name]}", values[safe],
                            re.I), (name, values[safe])
        assert params[name].is_hidden(safe)
    # FS_OPTIONS: bit 0 continues the mission on an RC loss, bit 1 on a link loss
    bits = _ardupilot_values(_ardupilot_doc("ArduCopter/Parameters.cpp", "FS_OPTIONS"),
                             "Bitmask")
    assert bits[0] == "Continue if in Auto on RC failsafe"
    assert bits[1] == "Continue if in Auto on GCS failsafe"
    copter = (ARDUPILOT_SRC / "ArduCopter/Copter.h").read_text()
    assert re.search(r"RC_CONTINUE_IF_AUTO\s*= \(1<<0\)", copter)
    assert re.search(r"GCS_CONTINUE_IF_AUTO\s*= \(1<<1\)", copter)
    assert params["FS_OPTIONS"].bits == 0b11
    # SmartRTL's buffer, as AP_SmartRTL.h defines it
    smart = (ARDUPILOT_SRC / "libraries/AP_SmartRTL/AP_SmartRTL.h").read_text()
    srtl = profile("ardupilot").smartrtl
    assert re.search(rf"SMARTRTL_POINTS_DEFAULT\s+{srtl.points}\b", smart)
    assert re.search(rf"SMARTRTL_POINTS_MAX\s+{srtl.points_max}\b", smart)
    assert re.search(rf"SMARTRTL_ACCURACY_DEFAULT\s+{srtl.accuracy_m:g}\.0f", smart)


def _px4_values(name: str) -> dict:
    """{value: meaning} (or {bit: meaning}) of PX4 parameter ``name``, from its
    definition's comment block."""
    for path in (PX4_SRC / "src/modules").rglob("*_params.c"):
        text = path.read_text(errors="replace")
        found = re.search(rf"/\*\*((?:(?!\*/).)*)\*/\s*PARAM_DEFINE_INT32\({name},", text, re.S)
        if found:
            return {int(k): v.strip() for k, v in
                    re.findall(r"@(?:value|bit) (\d+) ([^\n]*)", found.group(1))}
    raise AssertionError(f"{name} not defined in {PX4_SRC}")


#: the hidden-safe value's meaning, as PX4's documentation says it
PX4_SAFE = {"COM_LOW_BAT_ACT": "Return at critical level, land at emergency level",
            "RTL_TYPE": "reverse mission path, whichever is closer",
            "NAV_DLL_ACT": "Return mode", "NAV_RCL_ACT": "Return mode",
            "GF_ACTION": "Return mode", "COM_POS_LOW_ACT": "Land"}


@pytest.mark.skipif(not PX4_SRC.is_dir(), reason="no PX4 sources at /opt/px4")
def test_px4_failsafes_are_the_firmware_s_own():
    params = _parameters("px4")
    assert set(PX4_SAFE) | {"COM_DLL_EXCEPT", "COM_RCL_EXCEPT"} == set(params)
    for name, meaning in PX4_SAFE.items():
        values = _px4_values(name)
        # every documented value is worded (1, COM_LOW_BAT_ACT's deprecated Return, is
        # an enum value of failsafe.h no longer documented)
        assert set(values) <= set(params[name].actions), name
        assert meaning in values[int(params[name].safe)], (name, values)
        assert params[name].is_hidden(params[name].safe)
    for name in ("COM_DLL_EXCEPT", "COM_RCL_EXCEPT"):
        assert _px4_values(name)[0] == "Mission"
        assert params[name].bits == 0b1
    # the mission-path returns: RTL_TYPE 2 and 4, and nothing else, are hidden
    assert {v for v in params["RTL_TYPE"].actions if params["RTL_TYPE"].is_hidden(v)} == {2, 4}


# -- the preflight, on the simulator ------------------------------------------------------
def _fleet(planned, firmware, tmp_path):
    lat, lon, alt = planned.launch
    return quick_fleet(3, firmware, homes=[(lat, lon, alt)] * 3, track_dir=tmp_path / "tracks")


def _urls(fleet, firmware):
    urls = fleet.urls()
    return [a for u in (urls[:1] if firmware == "px4" else urls) for a in ("--connect", u)]


@pytest.mark.parametrize("firmware, named", [
    ("ardupilot", ["BATT_FS_LOW_ACT = 2, RTL: a climb to RTL_ALT and a straight line home",
                   "FS_THR_ENABLE = 1, RTL", "FS_OPTIONS = 16"]),
    ("px4", ["RTL_TYPE = 0, a climb to RTL_RETURN_ALT and a straight line",
             "COM_DLL_EXCEPT = 0", "COM_RCL_EXCEPT = 0"])])
def test_a_vehicle_whose_failsafe_leaves_the_proof_is_refused_before_arming(
        planned, tmp_path, capsys, firmware, named):
    fleet = _fleet(planned, firmware, tmp_path)
    out = tmp_path / "flight"
    try:
        code = main(["fly", str(planned.dir), *_urls(fleet, firmware), "--connect-timeout", "30",
                     "-o", str(out)])
        held = {s: dict(fleet.vehicle(s).params) for s in (1, 2, 3)}
    finally:
        fleet.stop()
    err = capsys.readouterr().err.strip().splitlines()   # the events, then the error
    print(err[-1])
    assert code == 2
    assert err[-1].startswith("gcs fly: error: vehicles 1, 2, 3: ")   # the same, said once
    for text in named:
        assert text in err[-1]
    assert "add --set-failsafes" in err[-1]
    for sysid in (1, 2, 3):
        events = [e["event"] for e in read_track(track_path(tmp_path / "tracks", sysid)).events]
        assert "armed" not in events                    # nothing armed
        booted = flavour(firmware).params                 # nothing written
        assert {k: held[sysid][k] for k in booted} == booted
    report = json.loads((out / "flight.json").read_text())
    assert not report["failsafes"]["1"].get("set")


#: what --set-failsafes leaves the simulated vehicles holding, and what they held
SET = {"ardupilot": {"BATT_FS_LOW_ACT": (2, 4), "FS_THR_ENABLE": (1, 5), "FS_OPTIONS": (16, 19)},
       "px4": {"RTL_TYPE": (0, 4), "COM_DLL_EXCEPT": (0, 1), "COM_RCL_EXCEPT": (0, 1)}}


@pytest.mark.parametrize("firmware", ["ardupilot", "px4"])
def test_set_failsafes_writes_reads_back_records_and_restores(planned, tmp_path, firmware):
    from gcs.flight import Flight, FlyOptions

    fleet = _fleet(planned, firmware, tmp_path)
    out = tmp_path / "flight"
    out.mkdir()
    try:
        flight = Flight(planned.dir, fleet.urls()[:1] if firmware == "px4" else fleet.urls(),
                        FlyOptions(output=out, plot=False, set_failsafes=True, live=False,
                                   tlog=False))
        flight.prepare()
        flight.connect()
        flight.preflight.locate()
        flight.preflight.check_failsafes()
        flight.link.close()
        for sysid in (1, 2, 3):
            held = fleet.vehicle(sysid).params
            for name, (before, after) in SET[firmware].items():
                assert held[name] == after, (sysid, name)
            changes = flight.preflight.failsafes[sysid]["set"]
            assert {c["parameter"]: (c["previous"], c["value"]) for c in changes} == \
                SET[firmware]
        events = [e["event"] for e in flight.monitor.events]
        assert any(e.startswith("failsafes set: ") for e in events)
        assert any(e.startswith("known risk: ") and "lands where it is" in e for e in events)
        # what gcs fly writes into flight.json, restored by `gcs failsafes --restore`
        (out / "flight.json").write_text(json.dumps({"failsafes": {
            str(s): f for s, f in flight.preflight.failsafes.items()}}))
        assert main(["failsafes", "--restore", str(out), *_urls(fleet, firmware)]) == 0
        for sysid in (1, 2, 3):
            held = fleet.vehicle(sysid).params
            for name, (before, after) in SET[firmware].items():
                assert held[name] == before, (sysid, name)
    finally:
        fleet.stop()


def test_restore_without_a_flight_report_is_one_line(tmp_path, capsys):
    assert main(["failsafes", "--restore", str(tmp_path), "--connect", "tcp:127.0.0.1:1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "flight.json: no such file" in err[0]
