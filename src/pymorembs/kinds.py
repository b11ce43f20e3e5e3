"""The kinds a job and the Python API choose from, each written once with the values it takes.

Every list of kinds of the library comes from here: the frame types (``[frame] type``), the
damping kinds (``[damping] kind``, :class:`~pymorembs.body.Damping`), the interface kinds
(``[[interface]] kind``, :class:`~pymorembs.preparation.interface.InterfaceSpec`) and the reference
kinds (``[band] reference``). Each kind is a :class:`Kind`, a string enum whose members compare
equal to their names (``FrameType.TANGENT == "tangent"``) and carry the :class:`Parameter` s the
kind takes besides its name. The job parser checks against them, the app's page builds its lists
and forms from them (served by ``GET /api/schema``). The files a job can write are the kinds of
the export registry (:mod:`pymorembs.export.registry`), the methods those of the method registry
(:mod:`pymorembs.methods`).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum
from typing import Any, Self

__all__ = [
    "DampingKind",
    "FrameType",
    "InterfaceKind",
    "Kind",
    "Parameter",
    "ReferenceKind",
    "choices",
]


@dataclass(frozen=True)
class Parameter:
    """A value a kind takes besides its name (a key of the job table beside ``kind``).

    Attributes
    ----------
    name : str
        The key (``"stiffness"``).
    type : {"float", "int"}
        The value's type.
    unit : str
        The unit, ``""`` for a dimensionless value or a node id.
    meaning : str
        What it is, a few words.
    required : bool
        The kind needs it; otherwise it has a default (None: the library's own).
    """

    name: str
    type: str
    unit: str
    meaning: str
    required: bool = False

    def to_json(self) -> dict[str, Any]:
        """The parameter as the served schema shows it."""
        return {"name": self.name, "type": self.type, "unit": self.unit,
                "meaning": self.meaning, "required": self.required}  # fmt: skip


class Kind(StrEnum):
    """A kind: its name (the member's value) and :attr:`parameters`, the values it takes."""

    parameters: tuple[Parameter, ...]

    def __new__(cls, name: str, parameters: tuple[Parameter, ...] = ()) -> Kind:
        member = str.__new__(cls, name)
        member._value_ = name
        member.parameters = parameters
        return member

    @classmethod
    def names(cls) -> tuple[str, ...]:
        """Every kind's name, in the order of the definition."""
        return tuple(member.value for member in cls)

    @classmethod
    def lookup(cls, value: object) -> Self | None:
        """The kind named ``value`` (a member or its name), None if ``value`` names none.

        The typed fields of the library (``Frame.kind``, ``Damping.kind``,
        ``InterfaceSpec.kind``) take a name at construction and store the kind through it.
        """
        if isinstance(value, str):
            return cls._value2member_map_.get(str(value))  # type: ignore[return-value]
        return None

    @property
    def keys(self) -> tuple[str, ...]:
        """The names of the kind's parameters."""
        return tuple(parameter.name for parameter in self.parameters)

    @classmethod
    def to_json(cls) -> dict[str, list[dict[str, Any]]]:
        """Every kind with its parameters, as the served schema shows them."""
        return {member.value: [p.to_json() for p in member.parameters] for member in cls}


class FrameType(Kind):
    """``[frame] type``: the floating frame of reference (paper section 2.1)."""

    TANGENT = "tangent", (Parameter("node", "int", "", "the node the frame holds", True),)
    BUCKENS = "buckens"
    NONE = "none"


class DampingKind(Kind):
    """``[damping] kind``: the damping model of the body (:class:`~pymorembs.body.Damping`)."""

    NONE = "none"
    RAYLEIGH = (
        "rayleigh",
        (
            Parameter("alpha", "float", "1/s", "mass-proportional factor"),
            Parameter("beta", "float", "s", "stiffness-proportional factor"),
        ),
    )
    MODAL = "modal", (Parameter("ratio", "float", "", "damping ratio of every mode", True),)


class InterfaceKind(Kind):
    """``[[interface]] kind``: how an interface node couples to its nodes (paper section 2.2)."""

    RIGID = "rigid"
    DISTRIBUTING = "distributing"
    BEAMS = (
        "beams",
        (
            Parameter("youngs_modulus", "float", "N/m^2", "Young's modulus of the beams"),
            Parameter("density", "float", "kg/m^3", "density of the beams"),
            Parameter("diameter", "float", "m", "diameter of the circular cross-section"),
            Parameter("poisson", "float", "", "Poisson's ratio of the beams"),
        ),
    )
    SPRINGS = (
        "springs",
        (
            Parameter("stiffness", "float", "N/m", "stiffness of each spring", True),
            Parameter("damping", "float", "N s/m", "viscous damping of each spring"),
        ),
    )


class ReferenceKind(Kind):
    """``[band] reference``: what the error of eq. 27 is measured against."""

    AUTO = "auto"
    FULL = "full"
    SURROGATE = "surrogate"


def choices(kind: type[Kind]) -> str:
    """The names of ``kind`` for a message: ``"'tangent', 'buckens' or 'none'"``."""
    quoted = [repr(name) for name in kind.names()]
    return f"{', '.join(quoted[:-1])} or {quoted[-1]}" if len(quoted) > 1 else quoted[0]
