"""Write the files a job asks for (``[export] outputs``) for one reduced model.

The kinds, their files and their writers are those of the export registry
(:data:`~pymorembs.export.registry.EXPORTS`; the table is in ``docs/jobs.md``, "Export kinds").
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from pymorembs.export.registry import EXPORTS, BodyOptions
from pymorembs.export.source import ExportSource, check_before_writing
from pymorembs.preparation import PreparedModel
from pymorembs.reduction.projection import ReducedModel


def write_outputs(
    model: ReducedModel,
    prepared: PreparedModel,
    name: str,
    outputs: Sequence[str],
    nodes: Sequence[int],
    folder: Path,
) -> list[str]:
    """Write the ``outputs`` of one reduced model into ``folder``; return the file names.

    Parameters
    ----------
    model : ReducedModel
        Checked first (:func:`~pymorembs.export.source.check_before_writing`).
    prepared : PreparedModel
        The prepared model it was reduced from.
    name : str
        The reduction's name (in file names).
    outputs : sequence of str
        Kinds of :data:`~pymorembs.export.registry.EXPORTS`; those the job writes itself
        (``report``) are passed over.
    nodes : sequence of int
        The frame nodes of the bodies for multibody codes (:class:`BodyOptions`).
    folder : Path
        The reduction's folder (it exists).

    Returns
    -------
    list of str
        The names of the written files: the kinds in the registry's order, the bodies for
        multibody codes after the other files.
    """
    check_before_writing(model, name)
    source = ExportSource(model, prepared, name)
    body = BodyOptions(tuple(nodes))
    kinds = [kind for kind in EXPORTS.values() if kind.name in outputs and kind.write is not None]
    names: list[str] = []
    for kind in sorted(kinds, key=lambda kind: kind.group == "body"):
        files = kind.file_names(name)
        options = body if kind.options is BodyOptions else None
        kind.write(source, options, tuple(folder / file for file in files))
        names += files
    return names


__all__ = ["write_outputs"]
