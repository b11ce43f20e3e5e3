"""Built-in example models: the rack of paper section 2 (beams, solid) and a rotating blade.

``EXAMPLES`` maps an example name to the function that builds the
:class:`~pymorembs.body.ElasticBody`, ``OPTIONS`` to the keyword options it takes from the
command line and job files; a new example is one more entry. Importing this package builds
nothing.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, fields
from typing import Any

from pymorembs.body import ElasticBody
from pymorembs.errors import UserError
from pymorembs.examples.blade import blade
from pymorembs.examples.rack_beams import rack_beams
from pymorembs.examples.rack_solid import INTERFACES as RACK_SOLID_INTERFACES
from pymorembs.examples.rack_solid import rack_solid

#: Example name -> model generator.
EXAMPLES: dict[str, Callable[..., ElasticBody]] = {
    "rack-beams": rack_beams,
    "rack-solid": rack_solid,
    "blade": blade,
}


@dataclass(frozen=True)
class ExampleOptions:
    """The options of the built-in examples, as ``[model]`` of a job and ``pymorembs example``
    give them; :data:`OPTIONS` says which example takes which, None is the example's default.

    Each field's ``metadata["minimum"]`` is the smallest value a job file may give.

    Attributes
    ----------
    dofs : int or None
        ``rack-solid``: about this many mesh dofs (at least 1000).
    interface : str or None
        ``rack-solid``: the coupling of interface node 2 (:data:`RACK_SOLID_INTERFACES` or
        ``"none"``).
    hub_radius : float or None
        ``blade``: distance of the blade's root from the rotation axis (m, >= 0).
    elements : int or None
        ``blade``: elements along the length (at least 4).
    """

    dofs: int | None = field(default=None, metadata={"minimum": 1000})
    interface: str | None = None
    hub_radius: float | None = field(default=None, metadata={"minimum": 0.0})
    elements: int | None = field(default=None, metadata={"minimum": 4})

    @classmethod
    def of(cls, name: str, options: Mapping[str, Any]) -> ExampleOptions:
        """The options ``options`` (by name) of the example ``name``.

        Raises
        ------
        UserError
            If the example does not take one of them.
        """
        refuse_unknown_options(name, options)
        return cls(**options)

    def given(self) -> dict[str, Any]:
        """The options that are set, by name (the keyword arguments of :func:`build_example`)."""
        values = {option.name: getattr(self, option.name) for option in fields(self)}
        return {name: value for name, value in values.items() if value is not None}


#: Example name -> the options (fields of :class:`ExampleOptions`) it accepts.
OPTIONS: dict[str, tuple[str, ...]] = {
    "rack-beams": (),
    "rack-solid": ("dofs", "interface"),
    "blade": ("hub_radius", "elements"),
}


def build_example(name: str, **options: Any) -> ElasticBody:
    """Build the built-in example model ``name`` (one of :data:`EXAMPLES`) with ``options``.

    Raises
    ------
    UserError
        If there is no example of that name, or it does not take one of the options.
    """
    try:
        factory = EXAMPLES[name]
    except KeyError:
        available = ", ".join(sorted(EXAMPLES))
        raise UserError(f"unknown example {name!r}; available: {available}") from None
    refuse_unknown_options(name, options)
    return factory(**options)


def refuse_unknown_options(name: str, options: Mapping[str, Any]) -> None:
    """A :class:`UserError` if the example ``name`` does not take one of ``options``."""
    accepted = OPTIONS.get(name, ())
    unknown = sorted(set(options) - set(accepted))
    if unknown:
        listed = ", ".join(accepted) or "none"
        raise UserError(f"example {name} has no option '{unknown[0]}' (options: {listed})")


__all__ = [
    "EXAMPLES",
    "OPTIONS",
    "RACK_SOLID_INTERFACES",
    "ExampleOptions",
    "blade",
    "build_example",
    "rack_beams",
    "rack_solid",
]
