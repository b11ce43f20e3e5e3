"""Stresses and strains of a displacement field of an elastic body, from its elements.

:func:`stress_operator` gives the sparse map from the body's dofs to the six tensor components at
the elements' integration points, at their nodes (extrapolated per element) or at the mesh's
nodes (averaged); :func:`von_mises` the equivalent stress. The conventions, and what they are
verified against: docs/stresses.md.
"""

from pymorembs.stress.extrapolation import extrapolation_matrix
from pymorembs.stress.operator import (
    COMPONENTS,
    LOCATIONS,
    QUANTITIES,
    StressOperator,
    stress_operator,
    von_mises,
)

__all__ = [
    "COMPONENTS",
    "LOCATIONS",
    "QUANTITIES",
    "StressOperator",
    "extrapolation_matrix",
    "stress_operator",
    "von_mises",
]
