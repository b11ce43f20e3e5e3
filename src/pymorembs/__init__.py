"""pymorembs: model order reduction of elastic bodies for flexible multibody simulation.

The reduction process follows Figs. 1 and 8 of Fehr and Eberhard, "Simulation process of flexible
multibody systems with non-modal model order reduction techniques" (Multibody System Dynamics,
2011; "the paper" of the docs and docstrings)::

    read / example --> ElasticBody --prepare--> PreparedModel --reduce--> ReducedBody
        --> .error(band) / .to_sid() / .to_exudyn() / .to_neweul() / .to_vtu() / .to_matrices()

Everything a script needs is here (:mod:`pymorembs.api`); the command line and job files are a
layer on it.
"""

__version__ = "0.1.0"

from pymorembs.analysis.time_domain import LoadCase, TimeResponse
from pymorembs.api import ErrorCurve, ReducedBody, example, facts, load, prepare, read, reduce
from pymorembs.body import DIRECTIONS, ConstraintEquations, Damping, DofTable, ElasticBody
from pymorembs.errors import AccuracyNotMet, NumericalError, PymorembsError, UserError
from pymorembs.methods import METHODS, method_options
from pymorembs.preparation import Frame, Port, PreparedModel
from pymorembs.preparation.interface import InterfaceSpec, select_nodes
from pymorembs.reduction.projection import ReducedModel
from pymorembs.stress import StressOperator, stress_operator, von_mises
from pymorembs.system import SecondOrderSystem

__all__ = [
    "DIRECTIONS",
    "METHODS",
    "AccuracyNotMet",
    "ConstraintEquations",
    "Damping",
    "DofTable",
    "ElasticBody",
    "ErrorCurve",
    "Frame",
    "InterfaceSpec",
    "LoadCase",
    "NumericalError",
    "Port",
    "PreparedModel",
    "PymorembsError",
    "ReducedBody",
    "ReducedModel",
    "SecondOrderSystem",
    "StressOperator",
    "TimeResponse",
    "UserError",
    "__version__",
    "example",
    "facts",
    "load",
    "method_options",
    "prepare",
    "read",
    "reduce",
    "select_nodes",
    "stress_operator",
    "von_mises",
]
