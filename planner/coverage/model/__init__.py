"""The coverage problem as the methods and the bounds see it.

Modules: problem (`CoverageProblem`, `Allocation`: the data), battery (each UAV's
`Battery`: what it allows, its ways out of and back to the bases), prepared (the
problem validated and laid out for the kernels; what each target can achieve),
routes (a route's times, flown in sorties), places and evaluation (sightings from
distinct UAVs at distinct places, the coverage time), classes (targets seen from
the same viewpoints, decided once), instances (random problems for the tests and
the benchmarks).
"""

from .battery import Batteries, Battery, beyond_battery, landing_bases
from .classes import target_classes
from .evaluation import coverage_counts, evaluate, last_needed_sighting, sighting_counts
from .prepared import Prepared, achievable, csc_transpose, owners, prepare
from .problem import CLOSED, FREE, Allocation, CoverageProblem, required_uavs

__all__ = ["CLOSED", "FREE", "Allocation", "Batteries", "Battery", "CoverageProblem",
           "Prepared", "achievable", "beyond_battery", "coverage_counts", "csc_transpose",
           "evaluate", "landing_bases", "last_needed_sighting", "owners", "prepare",
           "required_uavs", "sighting_counts", "target_classes"]
