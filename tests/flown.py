"""Judging a simulated flight: its outcome at a high speed-up, and its track."""


#: the outcome's line for a pair flown closer than the separation (gcs.flight.report)
TOO_CLOSE = "closer than the separation"


def problems_beside_guard(report: dict) -> list[str]:
    """The problems of a flight report's outcome other than the separation kept (or
    not) by the guard. At 25-100x a tenth of a wall second of jitter is 2.5-10 s of
    flight, so the fleet drifts off its separated schedule and keeping it apart then
    is the guard's job, at a loop too slow for that speed (judged on its own in
    sitl_tests/test_separation and tests/test_guard); anything else is a fault."""
    return [p for p in report["outcome"]["problems"] if TOO_CLOSE not in p]


#: the outcome's line for a battery reported empty in the air (gcs.flight.report)
EMPTY = "battery reported empty in the air"
#: the outcome's line for a vehicle that flew a mode gcs did not command (its failsafe's)
UNCOMMANDED = "flew in modes gcs did not command"


def problems_beside_pauses(report: dict) -> list[str]:
    """`problems_beside_guard`, and beside an empty battery or a failsafe's return of
    a vehicle the ground station held in the air (the guard, or a re-plan while it
    plans). On a 12-minute battery at 100x a held wall second is 100 s of flight: the
    ground station's 1-4 s of re-planning, or a hold resumed two loops later, outlast
    the 25 % reserve (3 minutes), where at 1x they cost a few seconds of it; and a
    vehicle held where the radio does not reach flies its link failsafe (set to
    SmartRTL: `gcs.sim.link_loss`) after 5 s of its time, 50 wall ms. A vehicle never
    held that ran its battery empty or flew a failsafe is a fault; so is every other
    problem."""
    held = {a["sysid"] for a in report["separation"].get("actions", [])}
    held |= {e.get("sysid") for e in report["events"] if e["event"] == "holding"}
    return [p for p in problems_beside_guard(report)
            if not ((EMPTY in p or UNCOMMANDED in p) and _vehicle_of(p) in held)]


def _vehicle_of(problem: str):
    """The system id a problem line starts with ("vehicle 2's battery ...")."""
    words = problem.split()
    return int(words[1].rstrip("'s")) if len(words) > 1 and words[0] == "vehicle" else None


def takeoffs_on_fresh_batteries(track) -> int:
    """Takeoffs in a simulator's track, asserting that each after the first came
    after a landing and a battery swap (the simulator's crew's)."""
    kinds = [e["event"] for e in track.events if e["event"] in
             ("takeoff", "landed", "battery swapped")]
    ups = [i for i, e in enumerate(kinds) if e == "takeoff"]
    for k in ups[1:]:
        assert kinds[k - 2:k] == ["landed", "battery swapped"], kinds
    return len(ups)
