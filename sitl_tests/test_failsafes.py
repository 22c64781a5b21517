"""Every failsafe read before arming, on the built-in simulator and on real
ArduPilot and PX4 SITL (issue 60): the firmware's own defaults refuse the
flight, naming the parameters; --set-failsafes writes the hidden-safe values,
and the vehicle itself, asked again, holds them (each a value the profile calls
hidden); the previous values are kept to restore, and restored.

Real SITL runs when the environment names its binaries (`source /opt/sitl.env`:
ARDUPILOT_SITL_BIN, ARDUPILOT_DEFAULTS, PX4_SITL_BIN); otherwise skipped, saying so."""

import pytest
from fleets import skip_unless_configured, start_backend

from autopilots import profile
from gcs import params
from gcs.flight import FailsafeRefused, Flight, FlyOptions
from gcs.flight.failsafes import restore

pytestmark = pytest.mark.timeout(600)


@pytest.mark.parametrize("backend", ["sim", "ardupilot", "px4"])
def test_failsafes_refused_then_set_read_back_and_restored(planned, tmp_path, backend):
    skip_unless_configured(backend)
    case = planned(0, backend)
    be = start_backend(backend, case.plan, tmp_path / "sitl")
    firmware = be.firmware
    parameters = [p for f in profile(firmware).failsafes for p in f.parameters]
    options = FlyOptions(output=tmp_path / "flight", live=False, plot=False, tlog=False,
                         connect_timeout_s=120.0, ready_timeout_s=180.0)
    flight = Flight(case.directory, be.urls(), options)
    try:
        flight.prepare()
        flight.output.mkdir(parents=True, exist_ok=True)
        flight.connect()
        flight.preflight.locate()
        with pytest.raises(FailsafeRefused) as refused:
            flight.preflight.check_failsafes()
        said = str(refused.value)
        assert "add --set-failsafes" in said
        # the firmware's defaults: RC loss RTL and no FS_OPTIONS (ArduPilot), RTL_TYPE 0
        # (PX4), named with their values
        assert ("FS_OPTIONS = 16" if firmware == "ardupilot" else "RTL_TYPE = 0") in said
        options.set_failsafes = True
        flight.preflight.check_failsafes()
        links = flight.monitor.links
        for sysid, link in sorted(links.items()):
            for p in parameters:
                held = params.read(link, p.name)
                assert held is not None, (sysid, p.name)
                gate_off = any(params.read(link, g) is not None and
                               test(params.read(link, g).value) for g, test in p.off)
                assert gate_off or p.is_hidden(held.value), (sysid, p.name, held.value)
            changes = flight.preflight.failsafes[sysid]["set"]
            assert changes and all(params.read(link, c["parameter"]).value == c["value"]
                                   for c in changes)
            assert restore(link, changes) == []
            assert all(params.read(link, c["parameter"]).value == c["previous"]
                       for c in changes)
    finally:
        if flight.link is not None:
            flight.link.close()
        be.stop()

