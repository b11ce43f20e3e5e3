"""pymorembs: model order reduction of elastic bodies for flexible multibody simulation.

The reduction process follows Fig. 1 and Fig. 8 of ``paper.md``::

    ElasticBody --prepare--> SecondOrderSystem --reduce--> Projection --> reduced body
"""

from pymorembs.body import ConstraintEquations, Damping, DofTable, ElasticBody
from pymorembs.errors import NumericalError, PymorembsError, UserError
from pymorembs.system import SecondOrderSystem

__version__ = "0.1.0"

__all__ = [
    "ConstraintEquations",
    "Damping",
    "DofTable",
    "ElasticBody",
    "NumericalError",
    "PymorembsError",
    "SecondOrderSystem",
    "UserError",
    "__version__",
]
