"""Built-in example models: the rack of paper section 2 (beams, solid) and a rotating blade.

``EXAMPLES`` maps an example name to the function that builds the
:class:`~pymorembs.body.ElasticBody`, ``OPTIONS`` to the keyword options it takes from the
command line and job files; a new example is one more entry. Importing this package builds
nothing.
"""

from __future__ import annotations

from collections.abc import Callable
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
#: Example name -> the options (``dofs``, ``interface``) it accepts.
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
    unknown = sorted(set(options) - set(OPTIONS[name]))
    if unknown:
        accepted = ", ".join(OPTIONS[name]) or "none"
        raise UserError(f"example {name} has no option '{unknown[0]}' (options: {accepted})")
    return factory(**options)


__all__ = [
    "EXAMPLES",
    "OPTIONS",
    "RACK_SOLID_INTERFACES",
    "blade",
    "build_example",
    "rack_beams",
    "rack_solid",
]
