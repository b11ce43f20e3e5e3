"""Built-in example models: generators of the rack of paper section 2.

``EXAMPLES`` maps an example name to a function without arguments that builds the
:class:`~pymorembs.body.ElasticBody`; a new example is one more entry. Importing this package
builds nothing.
"""

from __future__ import annotations

from collections.abc import Callable

from pymorembs.body import ElasticBody
from pymorembs.errors import UserError
from pymorembs.examples.rack_beams import rack_beams

#: Example name -> model generator.
EXAMPLES: dict[str, Callable[[], ElasticBody]] = {"rack-beams": rack_beams}


def build_example(name: str) -> ElasticBody:
    """Build the built-in example model ``name`` (one of :data:`EXAMPLES`).

    Raises
    ------
    UserError
        If there is no example of that name.
    """
    try:
        factory = EXAMPLES[name]
    except KeyError:
        available = ", ".join(sorted(EXAMPLES))
        raise UserError(f"unknown example {name!r}; available: {available}") from None
    return factory()


__all__ = ["EXAMPLES", "build_example", "rack_beams"]
