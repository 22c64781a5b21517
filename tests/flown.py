"""Judging a simulated flight's outcome at a high speed-up."""


#: the outcome's line for a pair flown closer than the separation (gcs.flight.report)
TOO_CLOSE = "closer than the separation"


def problems_beside_guard(report: dict) -> list[str]:
    """The problems of a flight report's outcome other than the separation kept (or
    not) by the guard. At 25-100x a tenth of a wall second of jitter is 2.5-10 s of
    flight, so the fleet drifts off its separated schedule and keeping it apart then
    is the guard's job, at a loop too slow for that speed (judged on its own in
    sitl_tests/test_separation and tests/test_guard); anything else is a fault."""
    return [p for p in report["outcome"]["problems"] if TOO_CLOSE not in p]
