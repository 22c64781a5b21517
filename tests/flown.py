"""Judging a simulated flight's outcome at a high speed-up."""


def problems_beside_guard(report: dict) -> list[str]:
    """The problems of a flight report's outcome other than the separation guard's
    holds. At 25-100x a tenth of a wall second of jitter is 2.5-10 s of flight, so
    the fleet drifts off its separated schedule and holding it then is the guard's
    job (judged on its own in sitl_tests/test_separation); anything else is a fault."""
    return [p for p in report["outcome"]["problems"] if "held by the separation guard" not in p]
