"""`gcs.contact`: a silence is the plan's when it starts where a radio shadow is
predicted, and is due back when that shadow ends at the pace the vehicle flies."""

import pytest
from hypothesis import given
from hypothesis import strategies as st

from gcs.contact import EARLY_LATE_S, WIDEN, Contact


def _flown(pace, lead_s=0.0):
    """A vehicle whose plan has a shadow from 300 to 420 s, flown at ``pace`` fleet s
    per monitor s, ``lead_s`` ahead of its plan, its waypoints every 60 fleet s."""
    c = Contact([[300.0, 420.0], [900.0, 960.0]], clock_rate=pace)
    for f in range(0, 300, 60):
        c.mark((f - lead_s) / pace, f)
    return c


@given(pace=st.floats(1.0, 100.0), lead=st.floats(-15.0, 15.0))
def test_a_silence_entering_a_predicted_shadow_is_due_back_at_its_end(pace, lead):
    c = _flown(pace, lead)
    heard = (300.0 - lead) / pace                 # last heard where the shadow starts
    q = c.expected(heard, lost_after_s=5.0)
    assert q is not None and q.window == (300.0, 420.0)
    back = (420.0 - lead) / pace                  # where the shadow ends, at that pace
    assert back <= q.due_s <= back + (EARLY_LATE_S + abs(lead)) / pace + 1e-9
    assert q.overdue_s == pytest.approx(q.due_s + 5.0 + WIDEN * (420.0 - 300.0) / pace)


def test_a_silence_where_contact_is_predicted_is_not_the_plans():
    c = _flown(10.0)
    assert c.expected(200.0 / 10.0, lost_after_s=5.0) is None          # 100 s before it
    assert c.expected(500.0 / 10.0, lost_after_s=5.0) is None          # after it


def test_the_pace_is_measured_on_the_plan_not_assumed():
    """A vehicle flying its plan at half the pace its clock runs (held, slowed) is due
    back twice as late."""
    c = Contact([[300.0, 420.0]], clock_rate=20.0)
    for f in range(0, 300, 60):
        c.mark(f / 10.0, f)                       # 10 fleet s per monitor s, not 20
    assert c.pace == pytest.approx(10.0)
    q = c.expected(30.0, lost_after_s=2.0)
    assert q.due_s == pytest.approx(30.0 + 120.0 / 10.0 + EARLY_LATE_S / 10.0)


def test_the_pace_is_read_on_the_vehicles_own_clock_not_when_its_reports_are_read():
    """A ground station reads a sped-up vehicle's reports in bursts (here five
    waypoints' reports within 0.6 s at 100x): on the monitor's clock that is 500
    fleet s per s. By its own clock it flies on schedule, and it is due back when
    the shadow ends at 100; where it was when last heard is read on its own clock
    too, whenever the monitor last read it."""
    c = Contact([[300.0, 420.0]], clock_rate=100.0)
    for f in range(0, 300, 60):
        c.mark(1.0 if f < 150 else 1.6, f, own_s=1000.0 + f)
    assert c.progress == pytest.approx(1.0) and c.pace == pytest.approx(100.0)
    q = c.expected(3.0, lost_after_s=2.0, own_s=1300.0)
    assert q.fleet_s == pytest.approx(300.0) and q.window == (300.0, 420.0)
    assert q.due_s == pytest.approx(3.0 + 120.0 / 100.0 + EARLY_LATE_S / 100.0)


def test_shadows_a_moment_of_contact_apart_are_one_silence():
    """A contact predicted for less than a vehicle may be early or late by is not
    counted on: a silence entering the first shadow is due back after the second."""
    c = Contact([[300.0, 420.0], [420.0 + EARLY_LATE_S - 1.0, 700.0], [800.0, 900.0]],
                clock_rate=10.0)
    assert c.windows == [(300.0, 700.0), (800.0, 900.0)]
    for f in range(0, 300, 60):
        c.mark(f / 10.0, f)
    assert c.expected(30.0, lost_after_s=2.0).window == (300.0, 700.0)


def test_a_new_mission_forgets_the_old_clock():
    c = _flown(10.0)
    c.restart([[50.0, 80.0]])
    assert c.fleet_time(100.0) is None and c.expected(100.0, 5.0) is None
    c.mark(100.0, 40.0)
    assert c.expected(100.0, 5.0).window == (50.0, 80.0)
