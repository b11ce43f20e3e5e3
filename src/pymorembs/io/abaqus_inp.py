"""The model data of an Abaqus input file: nodes, elements, parts, instances and the assembly.

:func:`read_inp` reads an ``.inp`` file (and the files it includes) into an :class:`InpModel`:
every node with its global coordinates and the id pymorembs gives it, and the element blocks
(read lazily: their connectivity is parsed only when a reader needs it, e.g. to derive the
equation order of a ``FORMAT=COORDINATE`` matrix file with :func:`derive_dof_table`).

What is read
    ``*NODE`` (parameters ``NSET``, ``INPUT=file``, ``SYSTEM=R`` only; data lines
    ``label, x[, y[, z]]``, missing coordinates are 0), ``*ELEMENT`` (``TYPE``, ``ELSET``,
    ``INPUT=file``; data lines ``label, node, node, ...``, continued on the next line after a
    trailing comma), ``*NSET`` and ``*ELSET`` (labels, names of other sets, ``GENERATE``),
    ``*SOLID SECTION``, ``*MATERIAL`` with ``*ELASTIC``, ``*BOUNDARY`` (kept with the step it
    belongs to, :func:`boundary_dofs`), ``*STEP`` ... ``*END STEP`` and a ``*FREQUENCY,
    SOLVER=MATRIXSTORAGE`` step (CalculiX), ``*PART`` ... ``*END PART``, ``*ASSEMBLY`` ...
    ``*END ASSEMBLY``, ``*INSTANCE, NAME=..., PART=...`` ... ``*END INSTANCE`` and ``*INCLUDE,
    INPUT=file`` (relative to the including file). Keyword lines ending in a comma continue on
    the next line; ``**`` comments and blank lines are skipped; ``D`` exponents are accepted.
    Every other keyword is skipped, except those that move nodes or turn their dof directions,
    which are refused with an explanation: ``*SYSTEM``, ``*TRANSFORM``, ``*NMAP``, ``*NGEN``,
    ``*NFILL``, ``*NCOPY``.

Parts and instances (the layout Abaqus/CAE writes by default)
    The nodes and elements of a part exist once per ``*INSTANCE`` of it; an instance may hold
    nodes and elements of its own (the mesh of an independent instance). The coordinates of an
    instance are those of its part moved by the data lines of ``*INSTANCE`` (Abaqus Keywords
    Reference): an optional first line ``tx, ty, tz`` (a translation) and an optional second
    line ``ax, ay, az, bx, by, bz, angle`` (a rotation by ``angle`` degrees, right-handed, about
    the axis from point a to point b). The translation is applied first, then the rotation.
    Nodes defined in the assembly itself (reference points) keep their coordinates.

Node ids
    A model without parts keeps the node labels. With parts the labels of different instances
    repeat, so the ids are: the labels themselves when they are unique across the whole model
    (one instance, for example), else ``k * 10**d + label`` where ``k`` counts the instances in
    ``*INSTANCE`` order (the assembly's own nodes come last) and ``10**d`` is the first power of
    ten above every label (labels up to 518: ``d = 3``, so node 7 of the second instance is
    2007). :attr:`InpModel.id_rule` says which rule was used.

Node order
    Abaqus numbers the nodes of a model in the order the input file defines them: the model's
    own nodes, then each instance (the nodes of its part, then its own), then the assembly's
    nodes. :attr:`InpModel.node_ids` follows that order; :func:`derive_dof_table` can also sort
    by label within each instance, and the reader that uses it proves which order fits.
"""

from __future__ import annotations

import io
import os
import re
import warnings
from collections.abc import Iterator
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Literal

import numpy as np

from pymorembs.arrays import sorted_unique
from pymorembs.body import DofTable
from pymorembs.errors import located_error
from pymorembs.io.compressed import original_path
from pymorembs.io.element_surface import SurfaceElements
from pymorembs.io.reader_support import read_text
from pymorembs.io.solid_mesh import SolidBlock
from pymorembs.surface import SURFACE_ELEMENTS

__all__ = [
    "ABAQUS_DOF_NAMES",
    "ABAQUS_SOLID_TYPES",
    "ABAQUS_SURFACE_TYPES",
    "MAX_LABEL",
    "Boundary",
    "BoundaryDofs",
    "ElementBlock",
    "ElementSet",
    "InpModel",
    "Material",
    "Placement",
    "Scope",
    "SolidSection",
    "ascii_data",
    "boundary_dofs",
    "derive_dof_table",
    "element_dofs",
    "integer_field",
    "keyword_blocks",
    "named_node_sets",
    "node_sets",
    "parse_keyword",
    "read_inp",
    "solid_blocks",
    "surface_elements",
    "surface_kind",
]

PathLike = str | os.PathLike[str]

#: Abaqus degrees of freedom beyond 1-6 (Abaqus Analysis User's Guide, "Conventions").
ABAQUS_DOF_NAMES: dict[int, str] = {
    7: "the warping amplitude of open-section beams",
    8: "a pore, hydrostatic fluid or acoustic pressure",
    9: "an electric potential",
    10: "a connector material flow",
    11: "a temperature (or normalized concentration)",
}
#: Largest Abaqus node or element label (32-bit).
MAX_LABEL = 2**31 - 1

_KEYWORD = re.compile(r"(?m)^[ \t]*\*(?!\*)")
_COMMENT_LINE = re.compile(r"(?m)^[ \t]*\*\*.*$")
_CONTINUED = re.compile(r",[ \t]*\n")
_TRAILING_COMMA = re.compile(r"(?m),[ \t]*$")
_REFUSED = {
    "SYSTEM": "*SYSTEM gives node coordinates in a local system, which pymorembs does not "
    "convert; give the nodes in the global system",
    "TRANSFORM": "*TRANSFORM puts the dofs of nodes in local directions, so the matrices are not "
    "in global ux..rz; remove the transformation before generating the matrices",
    "NMAP": "*NMAP moves nodes, which pymorembs does not do; write the final coordinates",
    "NGEN": "nodes generated by *NGEN are not read; write every node in a *NODE block",
    "NFILL": "nodes generated by *NFILL are not read; write every node in a *NODE block",
    "NCOPY": "nodes generated by *NCOPY are not read; write every node in a *NODE block",
}


def integer_field(
    path: Path, line: int | None, text: str, what: str, positive: bool = False
) -> int:
    """An integer field of an Abaqus file (a label, dof or count), range-checked to 32 bits.

    Raises ``file:line: <what> '<text>' is not an integer`` or ``... is out of range``; with
    ``positive`` a value below 1 is out of range too.
    """
    try:
        value = int(text)
    except ValueError:
        raise located_error(path, line, f"{what} {text!r} is not an integer") from None
    if abs(value) > MAX_LABEL or (positive and value < 1):
        limit = "1 to 2**31 - 1" if positive else "at most 2**31 - 1"
        raise located_error(path, line, f"{what} {text!r} is out of range ({limit})")
    return value


def ascii_data(path: Path, text: str, first_line: int, comment: str = "**") -> str:
    """``text`` for NumPy's parsers: ASCII only, or a one-line error at the first other character.

    Abaqus writes data lines in ASCII; other characters may stand in comments (from ``comment``
    to the end of the line), which are then removed (line numbers stay). NumPy's text parsers
    must not see them: ``np.loadtxt`` of NumPy 2.4 reads freed memory on some non-ASCII
    characters in an integer field (e.g. ``"\U000c6c13 1 2"``) and may crash.
    """
    if text.isascii():
        return text
    lines = text.split("\n")
    for offset, line in enumerate(lines):
        data = line.split(comment, 1)[0]
        if not data.isascii():
            character = next(c for c in data if not c.isascii())
            raise located_error(
                path,
                first_line + offset,
                f"character {character!r} in a data line; Abaqus writes numbers in ASCII",
            )
        lines[offset] = data
    return "\n".join(lines)


# ============================================================================ the model
@dataclass(frozen=True, eq=False)
class Placement:
    """Where an instance lies: ``x -> a + R(angle, b - a) (x + translation - a)``.

    ``angle`` in degrees; ``axis`` is ``None`` for a pure translation.
    """

    translation: np.ndarray = field(default_factory=lambda: np.zeros(3))
    axis: tuple[np.ndarray, np.ndarray] | None = None
    angle: float = 0.0

    @property
    def identity(self) -> bool:
        return not np.any(self.translation) and (self.axis is None or self.angle == 0.0)

    def apply(self, xyz: np.ndarray) -> np.ndarray:
        """Global coordinates, shape (n, 3), of points ``xyz`` of the part."""
        moved = np.asarray(xyz, dtype=float) + self.translation
        if self.axis is None or self.angle == 0.0:
            return moved
        a, b = self.axis
        k = (b - a) / np.linalg.norm(b - a)
        theta = np.radians(self.angle)
        cross = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
        rotation = np.eye(3) + np.sin(theta) * cross + (1.0 - np.cos(theta)) * cross @ cross
        return a + (moved - a) @ rotation.T

    def describe(self) -> str:
        parts = []
        if np.any(self.translation):
            parts.append("translated by ({:g}, {:g}, {:g})".format(*self.translation))
        if self.axis is not None and self.angle != 0.0:
            a, b = self.axis
            axis = "({:g}, {:g}, {:g})-({:g}, {:g}, {:g})".format(*a, *b)
            parts.append(f"rotated by {self.angle:g} degrees about the axis {axis}")
        return " and ".join(parts) if parts else "not moved"


@dataclass(frozen=True, eq=False)
class Scope:
    """A set of nodes with their own labels: the model itself, one instance, or the assembly."""

    kind: Literal["model", "instance", "assembly"]
    name: str
    part: str | None = None
    placement: Placement = field(default_factory=Placement)
    path: Path | None = None
    line: int | None = None

    def describe(self) -> str:
        if self.kind == "instance":
            return f"instance {self.name} (part {self.part})"
        return "the assembly" if self.kind == "assembly" else "the model"


@dataclass(frozen=True, eq=False)
class ElementBlock:
    """One ``*ELEMENT`` block of a scope; the connectivity is parsed on demand."""

    type: str
    scope: int
    path: Path
    line: int
    text: str
    first_line: int
    elset: str | None = None

    def node_labels(self, scopes: tuple[Scope, ...]) -> tuple[np.ndarray, np.ndarray]:
        """Scope index and label of every node reference, flat arrays of equal length."""
        return self._parsed(scopes)[1:]

    def element_labels(self, scopes: tuple[Scope, ...]) -> np.ndarray:
        """The label of every element of the block, in the order of :meth:`node_labels`."""
        return self._parsed(scopes)[0]

    def _parsed(self, scopes: tuple[Scope, ...]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The parsed block, kept after the first call (the dof table and the mesh use it)."""
        parsed = self.__dict__.get("_parsed_table")
        if parsed is None:
            parsed = _parse_elements(self, scopes)
            object.__setattr__(self, "_parsed_table", parsed)
        return parsed


@dataclass(frozen=True, eq=False)
class ElementSet:
    """One ``*ELSET`` data block (or the ``ELSET=`` of an ``*ELEMENT`` block) of a scope; also
    one ``*NSET`` data block (:attr:`InpModel.node_sets`), whose ``labels`` are set for the
    ``NSET=`` of a ``*NODE`` block (then ``text`` is empty); ``instance`` is the ``INSTANCE=``
    of a ``*NSET`` in the assembly (its labels are that instance's nodes)."""

    name: str
    scope: int
    path: Path
    line: int
    text: str
    first_line: int
    generate: bool = False
    labels: np.ndarray | None = None
    instance: str | None = None


@dataclass(frozen=True, eq=False)
class Boundary:
    """One ``*BOUNDARY`` block: data lines ``node or node set, first dof[, last dof[, value]]``.

    ``step`` is 0 for the model data, else the number of its ``*STEP`` (from 1); ``new`` is its
    ``OP=NEW`` (it removes the boundary conditions defined before it).
    """

    scope: int
    path: Path
    line: int
    text: str
    first_line: int
    step: int
    new: bool = False


@dataclass(frozen=True, eq=False)
class SolidSection:
    """``*SOLID SECTION, ELSET=..., MATERIAL=...`` of a scope."""

    elset: str
    material: str
    scope: int
    path: Path
    line: int


@dataclass(frozen=True, eq=False)
class Material:
    """``*MATERIAL, NAME=...`` with its ``*ELASTIC`` data lines (``None``: no ``*ELASTIC``).

    ``elastic_type`` is the ``TYPE=`` of ``*ELASTIC`` (upper case, ``ISOTROPIC`` by default) and
    ``elastic`` its data lines split into fields (temperature-dependent data has several).
    """

    name: str
    path: Path
    line: int
    elastic_type: str | None = None
    elastic: tuple[tuple[str, ...], ...] | None = None
    elastic_line: int | None = None


@dataclass(frozen=True, eq=False)
class InpModel:
    """Nodes and element blocks of an Abaqus input file (see the module docstring).

    Attributes
    ----------
    path : Path
        The input file read.
    scopes : tuple of Scope
        The model, the instances in ``*INSTANCE`` order and the assembly (only those that hold
        nodes or elements).
    node_ids : ndarray of int, shape (n_nodes,)
        The id pymorembs gives each node, in Abaqus' numbering order.
    labels, node_scope : ndarray of int, shape (n_nodes,)
        Label of each node in its scope and the index of the scope in :attr:`scopes`.
    coordinates : ndarray, shape (n_nodes, 3)
        Global coordinates (instance placements applied), model length unit.
    elements : tuple of ElementBlock
        Element blocks; a block of a part appears once per instance of the part.
    id_rule : str
        How the ids were made from the labels, one sentence.
    uses_parts : bool
        Whether the file defines parts and an assembly.
    generated_elements : tuple of (Path, int) or None
        Where ``*ELGEN``/``*ELCOPY`` generate elements that :attr:`elements` lacks.
    elsets : tuple of ElementSet
        Element sets (a set of a part appears once per instance of the part).
    sections : tuple of SolidSection
        Solid sections (likewise per instance).
    materials : dict of str -> Material
        Materials by upper-case name.
    node_sets : tuple of ElementSet
        Node sets (``*NSET`` blocks and the ``NSET=`` of ``*NODE`` blocks; :func:`node_sets`).
    boundaries : tuple of Boundary
        The ``*BOUNDARY`` blocks in file order.
    matrix_storage_step : int or None
        The number of the first ``*STEP`` with ``*FREQUENCY, SOLVER=MATRIXSTORAGE`` (the step in
        which CalculiX writes its stiffness and mass matrices), or None.
    """

    path: Path
    scopes: tuple[Scope, ...]
    node_ids: np.ndarray
    labels: np.ndarray
    node_scope: np.ndarray
    coordinates: np.ndarray
    elements: tuple[ElementBlock, ...]
    id_rule: str
    uses_parts: bool
    generated_elements: tuple[Path, int] | None = None
    elsets: tuple[ElementSet, ...] = ()
    sections: tuple[SolidSection, ...] = ()
    materials: dict[str, Material] = field(default_factory=dict)
    node_sets: tuple[ElementSet, ...] = ()
    boundaries: tuple[Boundary, ...] = ()
    matrix_storage_step: int | None = None

    def element_rows(self, block: ElementBlock) -> np.ndarray:
        """Node indices of the block's elements, shape (elements, nodes per element).

        Raises
        ------
        UserError
            An element names a node that is not defined (file and line of the block).
        """
        labels = block.element_labels(self.scopes)
        scope, node_labels = block.node_labels(self.scopes)
        rows = self.index_of(scope, node_labels)
        if np.any(rows < 0):
            k = int(np.flatnonzero(rows < 0)[0])
            raise located_error(
                block.path,
                block.line,
                f"an element of this *ELEMENT, TYPE={block.type} block names node "
                f"{node_labels[k]}, which is not defined",
            )
        return rows.reshape(labels.size, -1)

    def index_of(self, scope: np.ndarray, label: np.ndarray) -> np.ndarray:
        """Node index of each (scope, label) pair, -1 where no such node exists."""
        scope = np.asarray(scope, dtype=np.int64)
        label = np.asarray(label, dtype=np.int64)
        out = np.full(label.shape, -1, dtype=np.int64)
        if not self.labels.size:
            return out
        low, high = int(self.labels.min()), int(self.labels.max())
        width, count = high - low + 1, len(self.scopes)
        if count * width <= 4 * self.labels.size + (1 << 20):  # labels dense enough: a table
            table = np.full(count * width, -1, dtype=np.int64)
            table[self.node_scope * width + (self.labels - low)] = np.arange(self.labels.size)
            inside = (label >= low) & (label <= high) & (scope >= 0) & (scope < count)
            out[inside] = table[scope[inside] * width + (label[inside] - low)]
            return out
        keys = self.node_scope * (MAX_LABEL + 1) + self.labels
        order = np.argsort(keys, kind="stable")
        wanted = scope * (MAX_LABEL + 1) + label
        pos = np.minimum(np.searchsorted(keys[order], wanted), keys.size - 1)
        hit = keys[order][pos] == wanted
        out[hit] = order[pos[hit]]
        return out

    def placements_note(self) -> str | None:
        """One sentence about the instances and how they were placed, or None without parts."""
        instances = [s for s in self.scopes if s.kind == "instance"]
        if not instances:
            return None
        listed = "; ".join(f"{s.name} of part {s.part} {s.placement.describe()}" for s in instances)
        plural = "s" if len(instances) != 1 else ""
        return f"{self.path.name}: {len(instances)} instance{plural}: {listed}; {self.id_rule}"


# ============================================================================ reading
@dataclass
class _NodeBlock:
    labels: np.ndarray
    xyz: np.ndarray
    path: Path
    text: str
    first_line: int

    def line_of(self, k: int) -> int:
        """Line number of the ``k``-th node of the block (for messages only)."""
        count = -1
        for offset, line in enumerate(self.text.split("\n")):
            stripped = line.strip()
            if stripped and not stripped.startswith("**"):
                count += 1
                if count == k:
                    return self.first_line + offset
        return self.first_line


@dataclass
class _Container:
    """Nodes and element blocks gathered for one part, instance, assembly or the model."""

    nodes: list[_NodeBlock] = field(default_factory=list)
    elements: list[tuple[str, Path, int, str, int, str | None]] = field(default_factory=list)
    elsets: list[tuple[str, Path, int, str, int, bool, str | None]] = field(default_factory=list)
    sections: list[tuple[str, str, Path, int]] = field(default_factory=list)
    nsets: list[ElementSet] = field(default_factory=list)  # scope set when the model is built
    boundaries: list[Boundary] = field(default_factory=list)  # likewise


@dataclass
class _Instance:
    name: str
    part: str
    placement: Placement
    path: Path
    line: int
    own: _Container = field(default_factory=_Container)


class _Reader:
    """The keyword-level state machine over the input file and its includes."""

    def __init__(self) -> None:
        self.model = _Container()
        self.assembly = _Container()
        self.parts: dict[str, tuple[str, _Container, Path, int]] = {}
        self.instances: list[_Instance] = []
        self.context = self.model
        self.where = "model"
        self.generated: tuple[Path, int] | None = None
        self.uses_parts = False
        self.materials: dict[str, Material] = {}
        self.material: str | None = None  # the *MATERIAL the material options belong to
        self.step = 0  # the number of the current (or last) *STEP
        self.matrix_storage_step: int | None = None

    def scan(self, path: Path, stack: tuple[Path, ...] = ()) -> None:
        resolved = path.resolve()
        if resolved in stack:
            raise located_error(path, None, "*INCLUDE loop: the file includes itself")
        text = read_text(path, "an Abaqus input file")
        for line, keyword, data, data_line in keyword_blocks(text):
            self.keyword(path, line, keyword, data, data_line, (*stack, resolved))

    def keyword(
        self, path: Path, line: int, text: str, data: str, data_line: int, stack: tuple[Path, ...]
    ) -> None:
        keyword, params = parse_keyword(text)
        if keyword in _REFUSED:
            raise located_error(path, line, _REFUSED[keyword])
        if keyword in ("ELGEN", "ELCOPY") and self.generated is None:
            self.generated = (path, line)
        handler = {
            "PART": self._part,
            "ENDPART": self._end_part,
            "ASSEMBLY": self._assembly,
            "ENDASSEMBLY": self._end_assembly,
            "INSTANCE": self._instance,
            "ENDINSTANCE": self._end_instance,
        }.get(keyword)
        if handler is not None:
            handler(path, line, params, data, data_line)
        elif keyword == "NODE":
            self._node(path, line, params, data, data_line)
        elif keyword == "ELEMENT":
            self._element(path, line, params, data, data_line)
        elif keyword == "ELSET":
            self._elset(path, line, params, data, data_line)
        elif keyword == "NSET":
            self._nset(path, line, params, data, data_line)
        elif keyword == "BOUNDARY":
            new = params.get("OP", "MOD").upper() == "NEW"
            block = Boundary(-1, path, line, data, data_line, self.step, new)
            self.context.boundaries.append(block)
        elif keyword == "STEP":
            self.step += 1
        elif keyword == "FREQUENCY":
            storage = params.get("SOLVER", "").upper() == "MATRIXSTORAGE"
            if storage and self.matrix_storage_step is None:
                self.matrix_storage_step = self.step
        elif keyword == "SOLIDSECTION":
            self._section(path, line, params)
        elif keyword == "MATERIAL":
            name = params.get("NAME")
            if not name:
                raise located_error(path, line, "*MATERIAL without NAME=")
            self.materials[name.upper()] = Material(name, path, line)
            self.material = name.upper()
        elif keyword == "ELASTIC":
            self._elastic(path, line, params, data, data_line)
        elif keyword == "INCLUDE":
            if "INPUT" not in params:
                raise located_error(path, line, "*INCLUDE without INPUT=file")
            self.scan(original_path(path).parent / params["INPUT"], stack)

    def _expect(self, path: Path, line: int, word: str, where: str) -> None:
        if self.where != where:
            raise located_error(
                path,
                line,
                f"*{word} inside {_WHERE[self.where]}; the input file's *PART/*ASSEMBLY/"
                "*INSTANCE structure is broken",
            )

    def _part(self, path: Path, line: int, params: dict[str, str], *_: object) -> None:
        self._expect(path, line, "PART", "model")
        name = params.get("NAME")
        if not name:
            raise located_error(path, line, "*PART without NAME=")
        if name.upper() in self.parts:
            first = self.parts[name.upper()]
            raise located_error(
                path, line, f"part {name} is defined twice (first in {first[2]}:{first[3]})"
            )
        container = _Container()
        self.parts[name.upper()] = (name, container, path, line)
        self.context, self.where, self.uses_parts = container, "part", True

    def _end_part(self, path: Path, line: int, *_: object) -> None:
        self._expect(path, line, "END PART", "part")
        self.context, self.where = self.model, "model"

    def _assembly(self, path: Path, line: int, *_: object) -> None:
        self._expect(path, line, "ASSEMBLY", "model")
        self.context, self.where, self.uses_parts = self.assembly, "assembly", True

    def _end_assembly(self, path: Path, line: int, *_: object) -> None:
        self._expect(path, line, "END ASSEMBLY", "assembly")
        self.context, self.where = self.model, "model"

    def _instance(
        self, path: Path, line: int, params: dict[str, str], data: str, data_line: int
    ) -> None:
        self._expect(path, line, "INSTANCE", "assembly")
        if "INSTANCE" in params or "LIBRARY" in params:
            raise located_error(
                path,
                line,
                "an instance imported from a previous analysis: its nodes are not in this input "
                "file; give the nodes as nodes.csv",
            )
        name, part = params.get("NAME"), params.get("PART")
        if not name or not part:
            raise located_error(path, line, "*INSTANCE needs NAME= and PART=")
        if any(i.name.upper() == name.upper() for i in self.instances):
            raise located_error(path, line, f"instance {name} is defined twice")
        instance = _Instance(name, part, _placement(path, data, data_line), path, line)
        self.instances.append(instance)
        self.context, self.where = instance.own, "instance"

    def _end_instance(self, path: Path, line: int, *_: object) -> None:
        self._expect(path, line, "END INSTANCE", "instance")
        self.context, self.where = self.assembly, "assembly"

    def _node(
        self, path: Path, line: int, params: dict[str, str], data: str, data_line: int
    ) -> None:
        system = params.get("SYSTEM", "R").upper()
        if system != "R":
            raise located_error(
                path,
                line,
                f"*NODE, SYSTEM={system}: only rectangular coordinates (SYSTEM=R) are supported",
            )
        if "INPUT" in params:
            path = original_path(path).parent / params["INPUT"]
            data, data_line = read_text(path, "a file of *NODE data lines"), 1
        labels, xyz = _parse_nodes(path, data, data_line)
        if labels.size:
            self.context.nodes.append(_NodeBlock(labels, xyz, path, data, data_line))
        if params.get("NSET"):
            node_set = ElementSet(params["NSET"], -1, path, line, "", data_line, labels=labels)
            self.context.nsets.append(node_set)

    def _element(
        self, path: Path, line: int, params: dict[str, str], data: str, data_line: int
    ) -> None:
        kind = "".join(params.get("TYPE", "").upper().split())
        if not kind:
            raise located_error(path, line, "*ELEMENT without TYPE=")
        if "INPUT" in params:
            path = original_path(path).parent / params["INPUT"]
            data, data_line = read_text(path, "a file of *ELEMENT data lines"), 1
        elset = params.get("ELSET") or None
        self.context.elements.append((kind, path, line, data, data_line, elset))

    def _elset(
        self, path: Path, line: int, params: dict[str, str], data: str, data_line: int
    ) -> None:
        name = params.get("ELSET")
        if not name:
            raise located_error(path, line, "*ELSET without ELSET=")
        generate = "GENERATE" in params
        self.context.elsets.append(
            (name, path, line, data, data_line, generate, params.get("INSTANCE") or None)
        )

    def _nset(
        self, path: Path, line: int, params: dict[str, str], data: str, data_line: int
    ) -> None:
        name = params.get("NSET")
        if not name:
            raise located_error(path, line, "*NSET without NSET=")
        generate = "GENERATE" in params
        instance = params.get("INSTANCE") or None  # a set of an instance's nodes, in the assembly
        self.context.nsets.append(
            ElementSet(name, -1, path, line, data, data_line, generate, instance=instance)
        )

    def _section(self, path: Path, line: int, params: dict[str, str]) -> None:
        elset, material = params.get("ELSET"), params.get("MATERIAL")
        if not elset or not material:
            raise located_error(path, line, "*SOLID SECTION needs ELSET= and MATERIAL=")
        self.context.sections.append((elset, material, path, line))

    def _elastic(
        self, path: Path, line: int, params: dict[str, str], data: str, data_line: int
    ) -> None:
        if self.material is None:
            raise located_error(path, line, "*ELASTIC outside a *MATERIAL")
        rows = tuple(
            tuple(f.strip() for f in text.split("**", 1)[0].split(",") if f.strip())
            for text in data.split("\n")
            if text.split("**", 1)[0].strip()
        )
        first = self.materials[self.material]
        self.materials[self.material] = Material(
            first.name,
            first.path,
            first.line,
            params.get("TYPE", "ISOTROPIC").upper(),
            rows,
            data_line,
        )

    # --------------------------------------------------------------- the model
    def finish(self, path: Path) -> InpModel:
        if self.parts and not self.instances:
            name, _, where, line = next(iter(self.parts.values()))
            raise located_error(
                where,
                line,
                f"part {name} is never instanced (no *INSTANCE of it in an *ASSEMBLY), so its "
                "nodes are not in the model",
            )
        scopes: list[Scope] = []
        containers: list[list[_Container]] = []
        if self.model.nodes or self.model.elements:
            scopes.append(Scope("model", path.name))
            containers.append([self.model])
        for instance in self.instances:
            entry = self.parts.get(instance.part.upper())
            if entry is None:
                raise located_error(
                    instance.path,
                    instance.line,
                    f"instance {instance.name} names part {instance.part}, which is not defined",
                )
            scopes.append(
                Scope(
                    "instance",
                    instance.name,
                    entry[0],
                    instance.placement,
                    instance.path,
                    instance.line,
                )
            )
            containers.append([entry[1], instance.own])
        if self.assembly.nodes or self.assembly.elements:
            scopes.append(Scope("assembly", "assembly"))
            containers.append([self.assembly])

        labels, xyz, owner = [], [], []
        elements: list[ElementBlock] = []
        elsets: list[ElementSet] = []
        sections: list[SolidSection] = []
        nsets: list[ElementSet] = []
        boundaries: list[Boundary] = []
        for index, (scope, group) in enumerate(zip(scopes, containers, strict=True)):
            blocks = [block for container in group for block in container.nodes]
            _check_unique(blocks, scope)
            for block in blocks:
                labels.append(block.labels)
                xyz.append(scope.placement.apply(block.xyz))
                owner.append(np.full(block.labels.size, index, dtype=np.int64))
            for container in group:
                for kind, where, line, text, first, elset in container.elements:
                    elements.append(ElementBlock(kind, index, where, line, text, first, elset))
                for name, where, line, text, first, generate, instance in container.elsets:
                    owner_scope = _instance_scope(scopes, instance, index)
                    elsets.append(ElementSet(name, owner_scope, where, line, text, first, generate))
                for elset, material, where, line in container.sections:
                    sections.append(SolidSection(elset, material, index, where, line))
                nsets += [
                    replace(node_set, scope=_instance_scope(scopes, node_set.instance, index))
                    for node_set in container.nsets
                ]
                boundaries += [replace(block, scope=index) for block in container.boundaries]
        if not (self.assembly.nodes or self.assembly.elements):  # its sets of instances' nodes
            nsets += [
                replace(node_set, scope=_instance_scope(scopes, node_set.instance, -1))
                for node_set in self.assembly.nsets
                if node_set.instance is not None
            ]
        label = np.concatenate(labels) if labels else np.zeros(0, dtype=np.int64)
        node_scope = np.concatenate(owner) if owner else np.zeros(0, dtype=np.int64)
        coordinates = np.concatenate(xyz) if xyz else np.zeros((0, 3))
        node_ids, rule = _node_ids(label, node_scope, scopes, self.uses_parts)
        return InpModel(
            path=path,
            scopes=tuple(scopes),
            node_ids=node_ids,
            labels=label,
            node_scope=node_scope,
            coordinates=coordinates,
            elements=tuple(elements),
            id_rule=rule,
            uses_parts=self.uses_parts,
            generated_elements=self.generated,
            elsets=tuple(elsets),
            sections=tuple(sections),
            materials=dict(self.materials),
            node_sets=tuple(nsets),
            boundaries=tuple(sorted(boundaries, key=_step_of)),
            matrix_storage_step=self.matrix_storage_step,
        )


def _instance_scope(scopes: list[Scope], instance: str | None, own: int) -> int:
    """The scope of a set: that of the instance its ``INSTANCE=`` names (-1: no such instance),
    else its own."""
    if instance is None:
        return own
    found = [
        k
        for k, s in enumerate(scopes)
        if s.kind == "instance" and s.name.upper() == instance.upper()
    ]
    return found[0] if found else -1


def _step_of(block: Boundary) -> int:
    """The sort key that puts the blocks of the model data first, then each step's (a stable
    sort keeps the file order within each)."""
    return block.step


_WHERE = {
    "model": "the model",
    "part": "a *PART",
    "assembly": "the *ASSEMBLY",
    "instance": "an *INSTANCE",
}


def read_inp(path: PathLike) -> InpModel:
    """Read the nodes, element blocks, parts and instances of an Abaqus input file.

    Parameters
    ----------
    path : path-like
        The ``.inp`` file. Rules and conventions are in the module docstring.

    Returns
    -------
    InpModel

    Raises
    ------
    UserError
        ``file:line: problem`` for a malformed or repeated node, a broken part/assembly
        structure, an unknown part, malformed instance data lines or a refused keyword.
    """
    reader = _Reader()
    reader.scan(Path(path))
    return reader.finish(Path(path))


def keyword_blocks(text: str) -> Iterator[tuple[int, str, str, int]]:
    """Every keyword of an Abaqus text: (line, keyword line, data text, first data line).

    A keyword line ending in a comma continues on the next line (joined here); the data text
    runs to the next keyword line and keeps its ``**`` comments and blank lines.
    """
    line, last = 1, 0
    match = _KEYWORD.search(text, 0)
    while match is not None:
        line += text.count("\n", last, match.start())
        last = match.start()
        end = _line_end(text, match.start())
        keyword = text[match.start() : end].strip()
        lines = 1
        while keyword.endswith(",") and end < len(text):  # continued keyword line
            following = _line_end(text, end + 1)
            keyword += text[end + 1 : following].strip()
            end, lines = following, lines + 1
        data_start = min(end + 1, len(text))
        match = _KEYWORD.search(text, data_start)
        data_end = match.start() if match is not None else len(text)
        yield line, keyword, text[data_start:data_end], line + lines


def parse_keyword(text: str) -> tuple[str, dict[str, str]]:
    """Keyword name (upper case, blanks removed) and parameters of a keyword line."""
    parts = text.lstrip()[1:].split(",")
    keyword = "".join(parts[0].upper().split())
    params: dict[str, str] = {}
    for part in parts[1:]:
        key, _, value = part.partition("=")
        key = " ".join(key.upper().split())
        if key:
            params[key] = value.strip().strip('"').strip("'")
    return keyword, params


def _line_end(text: str, start: int) -> int:
    end = text.find("\n", start)
    return len(text) if end < 0 else end


def _node_ids(
    labels: np.ndarray, node_scope: np.ndarray, scopes: list[Scope], uses_parts: bool
) -> tuple[np.ndarray, str]:
    """The ids of the nodes and the sentence that says how they were made."""
    if not uses_parts:
        return labels.copy(), "node ids are the *NODE labels"
    if sorted_unique(labels).size == labels.size:
        return labels.copy(), "node ids are the labels (unique across the model)"
    digits = len(str(int(np.abs(labels).max())))
    base = 10**digits
    ids = (node_scope + 1) * base + labels
    holding = sorted_unique(node_scope)
    where = ", ".join(f"{scopes[k].name}: {(k + 1) * base} + label" for k in holding.tolist())
    return ids, f"labels repeat across instances, so node ids are ({where})"


def _check_unique(blocks: list[_NodeBlock], scope: Scope) -> None:
    """A label defined twice in one scope is an error naming both lines."""
    if not blocks:
        return
    labels = np.concatenate([block.labels for block in blocks])
    ordered = np.sort(labels)
    repeated = ordered[1:] == ordered[:-1]
    if not repeated.any():
        return
    twice = sorted_unique(ordered[1:][repeated])
    hits = np.flatnonzero(np.isin(labels, twice))
    # the second occurrence of the first label that repeats, in file order
    seen: dict[int, int] = {}
    for k in hits.tolist():
        label = int(labels[k])
        if label in seen:
            first_k, second_k = seen[label], k
            break
        seen[label] = k
    else:  # pragma: no cover - hits always hold a repeat
        return
    where = [_locate(blocks, first_k), _locate(blocks, second_k)]
    (first_path, first_line), (path, line) = where
    in_scope = f" in {scope.describe()}" if scope.kind != "model" else ""
    raise located_error(
        path,
        line,
        f"node {label} is defined twice{in_scope} (first in {first_path}:{first_line})",
    )


def _locate(blocks: list[_NodeBlock], k: int) -> tuple[Path, int]:
    for block in blocks:
        if k < block.labels.size:
            return block.path, block.line_of(k)
        k -= block.labels.size
    return blocks[-1].path, blocks[-1].first_line


def _placement(path: Path, data: str, first_line: int) -> Placement:
    """The translation and rotation data lines of ``*INSTANCE``."""
    rows = [
        (first_line + k, line.strip().rstrip(","))
        for k, line in enumerate(data.split("\n"))
        if line.strip() and not line.strip().startswith("**")
    ]
    if len(rows) > 2:
        raise located_error(
            path,
            rows[2][0],
            "*INSTANCE has at most two data lines (a translation, then a rotation)",
        )
    values = []
    expected = ((3, "translation tx, ty, tz"), (7, "rotation ax, ay, az, bx, by, bz, angle"))
    for (line, text), (count, what) in zip(rows, expected[: len(rows)], strict=True):
        fields = [f.strip() for f in text.split(",")]
        if len(fields) != count:
            raise located_error(path, line, f"{len(fields)} values, expected the {what}")
        numbers = []
        for field_text in fields:
            try:
                number = float(field_text.replace("D", "E").replace("d", "e"))
            except ValueError:
                raise located_error(path, line, f"{field_text!r} is not a number") from None
            if not np.isfinite(number):
                raise located_error(path, line, f"{field_text!r} is not finite")
            numbers.append(number)
        values.append((line, np.array(numbers)))
    if not values:
        return Placement()
    translation = values[0][1]
    if len(values) == 1:
        return Placement(translation)
    line, rotation = values[1]
    a, b = rotation[:3], rotation[3:6]
    if not np.linalg.norm(b - a) > 0.0:
        raise located_error(path, line, "the rotation axis points a and b coincide")
    return Placement(translation, (a, b), float(rotation[6]))


# ============================================================================ data lines
def _parse_nodes(path: Path, data: str, first_line: int) -> tuple[np.ndarray, np.ndarray]:
    """Labels and coordinates of a block of ``*NODE`` data lines (vectorised; slow on error)."""
    text = ascii_data(path, _COMMENT_LINE.sub("", data), first_line)
    if not text.strip():
        return np.zeros(0, dtype=np.int64), np.zeros((0, 3))
    if "D" in text or "d" in text:
        text = text.replace("D", "E").replace("d", "e")
    first = next(line for line in text.split("\n") if line.strip())
    count = len(first.split(","))
    if 2 <= count <= 4:
        dtype = [("label", np.int64)] + [(f"x{k}", np.float64) for k in range(count - 1)]
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                table = np.loadtxt(io.StringIO(text), dtype=dtype, delimiter=",", ndmin=1)
        except (ValueError, OverflowError):
            table = None
        if table is not None:
            labels = np.ascontiguousarray(table["label"])
            xyz = np.zeros((labels.size, 3))
            for k in range(count - 1):
                xyz[:, k] = table[f"x{k}"]
            if np.all(np.abs(labels) <= MAX_LABEL) and np.all(np.isfinite(xyz)):
                return labels, xyz
    return _parse_nodes_slowly(path, data, first_line)


def _parse_nodes_slowly(path: Path, data: str, first_line: int) -> tuple[np.ndarray, np.ndarray]:
    """The same, line by line: irregular but valid lines, or the exact bad line."""
    labels: list[int] = []
    xyz: list[list[float]] = []
    for offset, line in enumerate(data.split("\n")):
        text = line.strip()
        if not text or text.startswith("**"):
            continue
        number = first_line + offset
        fields = [f.strip() for f in text.split(",")]
        node = integer_field(path, number, fields[0], "node label")
        coords = [0.0, 0.0, 0.0]
        for axis, field_text in enumerate(fields[1:4]):
            if not field_text:
                continue
            try:
                coords[axis] = float(field_text.replace("D", "E").replace("d", "e"))
            except ValueError:
                raise located_error(
                    path, number, f"coordinate {'xyz'[axis]} {field_text!r} is not a number"
                ) from None
            if not np.isfinite(coords[axis]):
                raise located_error(
                    path, number, f"coordinate {'xyz'[axis]} {field_text!r} is not finite"
                )
        labels.append(node)
        xyz.append(coords)
    return np.array(labels, dtype=np.int64), np.array(xyz, dtype=float).reshape(-1, 3)


def _parse_elements(
    block: ElementBlock, scopes: tuple[Scope, ...]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Element labels, and scope and label of every node reference of an element block
    (vectorised; element by element on error)."""
    text = ascii_data(block.path, _COMMENT_LINE.sub("", block.text), block.first_line)
    text = _TRAILING_COMMA.sub("", _CONTINUED.sub(",", text))
    if not text.strip():
        return (np.zeros(0, dtype=np.int64),) * 3
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            table = np.loadtxt(io.StringIO(text), dtype=np.int64, delimiter=",", ndmin=2)
    except (ValueError, OverflowError):
        table = None
    if table is not None and table.shape[1] >= 2:
        labels = table[:, 1:].ravel()
        if np.all((labels > 0) & (labels <= MAX_LABEL)) and np.all(
            (table[:, 0] > 0) & (table[:, 0] <= MAX_LABEL)
        ):
            return table[:, 0].copy(), np.full(labels.size, block.scope, dtype=np.int64), labels
    return _parse_elements_slowly(block, scopes)


def _parse_elements_slowly(
    block: ElementBlock, scopes: tuple[Scope, ...]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The same, element by element: ``instance.label`` references, or the exact bad line."""
    names = {s.name.upper(): k for k, s in enumerate(scopes) if s.kind == "instance"}
    scope_of: list[int] = []
    label_of: list[int] = []
    element_of: list[int] = []
    width: tuple[int, int] | None = None
    pending: list[str] = []
    start = None
    for offset, line in enumerate(block.text.split("\n")):
        text = line.strip()
        if not text or text.startswith("**"):
            continue
        number = block.first_line + offset
        start = number if not pending else start
        pending.extend(f.strip() for f in text.split(","))
        if text.endswith(","):
            pending.pop()
            continue
        fields, pending = pending, []
        if len(fields) < 2:
            raise located_error(
                block.path, number, f"element line with {len(fields)} field; expected label, nodes"
            )
        if width is not None and len(fields) != width[0]:
            raise located_error(
                block.path,
                number,
                f"element with {len(fields) - 1} nodes, but the element on line {width[1]} of "
                f"this *ELEMENT, TYPE={block.type} block has {width[0] - 1}",
            )
        width = width or (len(fields), number)
        element_of.append(
            integer_field(block.path, number, fields[0], "element label", positive=True)
        )
        for item in fields[1:]:
            scope, label = _node_reference(block, number, item, names)
            scope_of.append(scope)
            label_of.append(label)
    if pending:
        raise located_error(block.path, start, "the last element line ends with a comma")
    return (
        np.array(element_of, dtype=np.int64),
        np.array(scope_of, dtype=np.int64),
        np.array(label_of, dtype=np.int64),
    )


def _node_reference(
    block: ElementBlock, number: int, text: str, names: dict[str, int]
) -> tuple[int, int]:
    """(scope, label) of a node of an element: ``label``, or in the assembly ``instance.label``."""
    scope = block.scope
    if "." in text:
        instance, _, text = text.rpartition(".")
        if instance.upper() not in names:
            raise located_error(
                block.path, number, f"node {instance}.{text}: there is no instance {instance}"
            )
        scope = names[instance.upper()]
    return scope, integer_field(block.path, number, text, "node label", positive=True)


# ============================================================================ dofs of elements
_UX_UY_UZ = 0b000111
_UX_UY = 0b000011
_ALL = 0b111111
_PLANE_BEAM = 0b100011  # ux uy rz
_ROTATIONS = 0b111000
_TRANSLATIONS = -1  # ux uy uz in a 3-D model, ux uy in a planar one
_ROTARY = -2  # rx ry rz in a 3-D model, rz in a planar one

#: (pattern, dofs) of the element types whose nodal dofs are known; first match wins.
_ELEMENT_DOFS: tuple[tuple[re.Pattern[str], int], ...] = tuple(
    (re.compile(pattern), mask)
    for pattern, mask in (
        (r"C3D(4|6|8|10|15|20|27)(R|I|S|RS)?", _UX_UY_UZ),  # continuum solids
        (r"SC(6|8)R", _UX_UY_UZ),  # continuum shells
        (r"COH3D(6|8)", _UX_UY_UZ),  # cohesive
        (r"CIN3D(8|12R|18R)", _UX_UY_UZ),  # solid infinite elements
        (r"M3D(3|4|4R|6|8|8R|9|9R)", _UX_UY_UZ),  # membranes
        (r"SFM3D(3|4|4R|6|8|8R)", _UX_UY_UZ),  # surface elements
        (r"T3D(2|3)", _UX_UY_UZ),  # trusses
        (r"(B31|B32|B33|PIPE31|PIPE32|FRAME3D)", _ALL),  # beams, pipes, frames
        (r"(S3|S3R|S4|S4R|S8R|STRI3|S3RS|S4RS|S4RSW)", _ALL),  # shells with six dofs
        (r"CP[SE](3|4|4R|4I|6|8|8R)", _UX_UY),  # plane stress and plane strain
        (r"T2D(2|3)", _UX_UY),
        (r"(B21|B22|B23|PIPE21|PIPE22|FRAME2D)", _PLANE_BEAM),
        (r"(MASS|SPRINGA|DASHPOTA)", _TRANSLATIONS),
        (r"ROTARYI", _ROTARY),
    )
)
_POINT_TYPES = ("MASS", "SPRINGA", "DASHPOTA", "ROTARYI")
_PLANAR = re.compile(r"(CP[SE]\w*|T2D\w*|B2\w*|PIPE2\w*|FRAME2D)")
#: (pattern, why its equations cannot be derived); checked after the known types.
_NOT_DERIVABLE: tuple[tuple[re.Pattern[str], str], ...] = tuple(
    (re.compile(pattern), why)
    for pattern, why in (
        (r"\w*H", "a hybrid element: Abaqus adds internal pressure or force variables"),
        (r"\w+M", "a modified element: its Abaqus internal nodes add equations"),
        (r"(S4R5|S8R5|S9R5|STRI65)", "a shell with 5 dofs at some nodes and 6 at others"),
        (r"B3\dOS\w*", "an open-section beam with a warping dof (7)"),
        (r"ELBOW\w*", "an elbow element with ovalization dofs"),
        (r"(DC|AC|DCC)\w*", "a heat transfer or acoustic element (no displacements)"),
        (r"(C|S|M|T|B|SC|CP[SE])\w*T", "a coupled temperature-displacement element (dof 11)"),
        (r"C\w*P", "a pore pressure element (dof 8)"),
        (r"C\w*E", "a piezoelectric element (dof 9)"),
        (r"(CAX|CGAX|SAX|MAX|MGAX)\w*", "an axisymmetric element (r-z dofs)"),
        (r"CPEG\w*", "a generalized plane strain element (with a reference node)"),
        (r"(SPRING|DASHPOT)(1|2)", "a spring or dashpot whose dofs its data lines choose"),
        (
            r"(CONN\w*|JOINT\w*|GAP\w*|ITS\w*|DCOUP\w*|KCOUP\w*|R[23]D\w*|RB[23]D\w*)",
            "a connector, gap, coupling or rigid element (constraints with Lagrange multipliers)",
        ),
        (r"V?U\d+", "a user element"),
        (r"Z\d+", "a substructure"),
    )
)


def element_dofs(kind: str, planar: bool = False) -> int | str:
    """The dofs an element type activates at its nodes, as a bit mask of ux..rz (bit 0 = ux).

    Parameters
    ----------
    kind : str
        The Abaqus element type, upper case (``"C3D10"``).
    planar : bool
        Whether the model is planar (2-D): point masses and axial springs then act in x, y.

    Returns
    -------
    int or str
        The mask, or a phrase saying why the equations of this type cannot be derived.
    """
    for pattern, mask in _ELEMENT_DOFS:
        if pattern.fullmatch(kind):
            if mask == _TRANSLATIONS:
                return _UX_UY if planar else _UX_UY_UZ
            if mask == _ROTARY:
                return 0b100000 if planar else _ROTATIONS
            return mask
    for pattern, why in _NOT_DERIVABLE:
        if pattern.fullmatch(kind):
            return why
    return "a type pymorembs does not know"


def derive_dof_table(
    model: InpModel, order: Literal["file", "label"] = "file"
) -> tuple[DofTable, str]:
    """The equations Abaqus gives the model: nodes in order, the active dofs of each in turn.

    A node's active dofs are the union of those of the elements that use it
    (:func:`element_dofs`); a node used by no element has none. Within a node the dofs are in
    the order 1..6.

    Parameters
    ----------
    model : InpModel
        The input file read.
    order : {"file", "label"}
        Node order: as the input file defines them (Abaqus' numbering), or sorted by label
        within each scope.

    Returns
    -------
    table : DofTable
        Node ids and directions of the equations.
    types : str
        The element types that gave the dofs, e.g. ``"C3D4"``.

    Raises
    ------
    UserError
        ``file:line: problem`` for an element type whose equations cannot be derived, an element
        that names an undefined node, generated elements, or a model without elements.
    """
    if model.generated_elements is not None:
        path, line = model.generated_elements
        raise located_error(
            path, line, "elements generated by *ELGEN/*ELCOPY are not read; cannot derive the dofs"
        )
    if not model.elements:
        raise located_error(model.path, None, "no *ELEMENT data: cannot derive the dofs")
    shaped = [block.type for block in model.elements if block.type not in _POINT_TYPES]
    planar = bool(shaped) and all(_PLANAR.fullmatch(kind) for kind in shaped)
    masks = np.zeros(model.node_ids.size, dtype=np.int64)
    types: list[str] = []
    for block in model.elements:
        mask = element_dofs(block.type, planar)
        if isinstance(mask, str):
            raise located_error(
                block.path,
                block.line,
                f"element type {block.type} is {mask}; pymorembs cannot tell which equations "
                "Abaqus gives it",
            )
        scope, label = block.node_labels(model.scopes)
        index = model.index_of(scope, label)
        if np.any(index < 0):
            k = int(np.flatnonzero(index < 0)[0])
            where = model.scopes[int(scope[k])]
            in_scope = f" in {where.describe()}" if where.kind != "model" else ""
            raise located_error(
                block.path,
                block.line,
                f"an element of this *ELEMENT, TYPE={block.type} block names node {label[k]}, "
                f"which is not defined{in_scope}",
            )
        np.bitwise_or.at(masks, index, mask)
        if block.type not in types:
            types.append(block.type)
    nodes = np.arange(model.node_ids.size)
    if order == "label":
        nodes = np.lexsort((model.labels, model.node_scope))
    used = nodes[masks[nodes] != 0]
    bits = (masks[used, None] >> np.arange(6)) & 1
    node_of, direction = np.nonzero(bits)
    table = DofTable(model.node_ids[used][node_of], direction)
    return table, " ".join(types)


# ============================================================================ solid elements
#: Abaqus element types with solid kinematics in :mod:`pymorembs.elements.solid`.
ABAQUS_SOLID_TYPES = {
    "C3D4": "tet4",
    "C3D10": "tet10",
    "C3D8": "hex8",
    "C3D20": "hex20",
    "C3D20R": "hex20r",
}


def solid_blocks(model: InpModel) -> list[SolidBlock] | str:
    """The solid elements of the model with their material, or why they cannot be used.

    Every element of a type of :data:`ABAQUS_SOLID_TYPES` must lie in the ``ELSET`` of a
    ``*SOLID SECTION`` of its scope whose ``*MATERIAL`` has ``*ELASTIC`` (``TYPE=ISOTROPIC``, one
    data line ``E, nu``). Point masses (``MASS``, ``ROTARYI``) are ignored; any other element
    type makes the mesh unusable (its stiffening would be missing).

    Parameters
    ----------
    model : InpModel

    Returns
    -------
    list of SolidBlock, or str
        The blocks (connectivity in :attr:`InpModel.node_ids`), or a sentence saying why the
        model gives no mesh.

    Raises
    ------
    UserError
        ``file:line: ...`` for an element that names an undefined node or a malformed
        ``*ELSET``.
    """
    name = model.path.name
    if model.generated_elements is not None:
        return f"{name} generates elements with *ELGEN/*ELCOPY, which are not read"
    other = sorted({b.type for b in model.elements} - set(ABAQUS_SOLID_TYPES) - {"MASS", "ROTARYI"})
    if other:
        return (
            f"{name} has elements of type {', '.join(other)}, whose geometric stiffness is not "
            f"implemented (solid types read: {', '.join(ABAQUS_SOLID_TYPES)})"
        )
    solid = [b for b in model.elements if b.type in ABAQUS_SOLID_TYPES]
    if not solid:
        return f"{name} has no solid elements ({', '.join(ABAQUS_SOLID_TYPES)})"
    sets = _element_sets(model)
    blocks: list[SolidBlock] = []
    for block in solid:
        kind = ABAQUS_SOLID_TYPES[block.type]
        labels = block.element_labels(model.scopes)
        if not labels.size:
            continue
        connectivity = model.node_ids[model.element_rows(block)]
        material = np.full(labels.size, -1, dtype=np.int64)
        found: list[Material] = []
        for section in model.sections:
            if section.scope != block.scope:
                continue
            members = sets.get((section.scope, section.elset.upper()))
            if members is None:
                return (
                    f"{section.path.name}:{section.line}: *SOLID SECTION names element set "
                    f"{section.elset}, which is not defined"
                )
            hit = np.isin(labels, members)
            if not np.any(hit):
                continue
            entry = model.materials.get(section.material.upper())
            if entry is None:
                return (
                    f"{section.path.name}:{section.line}: *SOLID SECTION names material "
                    f"{section.material}, which is not defined"
                )
            problem = _isotropic(entry)
            if isinstance(problem, str):
                return problem
            if entry not in found:
                found.append(entry)
            material[hit] = found.index(entry)
        if np.any(material < 0):
            label = int(labels[np.flatnonzero(material < 0)[0]])
            return (
                f"{block.path.name}:{block.line}: element {label} ({block.type}) lies in no "
                "*SOLID SECTION, so its material is not known"
            )
        for k, entry in enumerate(found):
            young, poisson = _isotropic(entry)  # type: ignore[misc]
            blocks.append(
                SolidBlock(
                    kind,
                    connectivity[material == k],
                    young,
                    poisson,
                    f"{block.path.name}:{block.line} *ELEMENT, TYPE={block.type}",
                    labels[material == k],
                )
            )
    return blocks


# ============================================================================ surface elements
#: Abaqus element types (regular expressions, the whole name) drawn on the body's surface, with
#: their kind in :mod:`pymorembs.surface`: solids (also continuum shells SC6R/SC8R), shells,
#: membranes and plane elements, beams, pipes and trusses. A beam may list an extra orientation
#: node after its own; it is not drawn.
ABAQUS_SURFACE_TYPES: tuple[tuple[str, str], ...] = (
    (r"C3D4[A-Z]*", "tet4"),
    (r"C3D10[A-Z]*", "tet10"),
    (r"C3D8[A-Z]*|SC8R", "hex8"),
    (r"C3D20[A-Z]*", "hex20"),
    (r"C3D6[A-Z]*|SC6R", "wedge6"),
    (r"C3D15[A-Z]*", "wedge15"),
    (r"C3D5[A-Z]*", "pyramid5"),
    (r"S3R?S?|STRI3|M3D3|CP[SE]3|CAX3", "tri3"),
    (r"STRI65|M3D6|CP[SE]6M?|CAX6M?", "tri6"),
    (r"S4R?5?|S4RS|S4RSW|M3D4R?|CP[SE]4[RI]?|CAX4[RI]?", "quad4"),
    (r"S8R5?|M3D8R?|CP[SE]8R?|CAX8R?", "quad8"),
    (r"B3[13]H?|PIPE31H?|T3D2H?|B2[13]H?|T2D2H?", "line2"),
    (r"B32H?|PIPE32H?|T3D3H?|B22H?|T2D3H?", "line3"),
)


def surface_kind(element_type: str) -> str | None:
    """The :mod:`pymorembs.surface` kind of an Abaqus element type, or None (not drawn)."""
    for pattern, kind in ABAQUS_SURFACE_TYPES:
        if re.fullmatch(pattern, element_type.upper()):
            return kind
    return None


def surface_elements(model: InpModel) -> SurfaceElements:
    """Every element of the model for the body's surface, whatever its section or material.

    Each ``*ELEMENT`` block of a type of :data:`ABAQUS_SURFACE_TYPES` becomes a block of its
    kind (a beam's orientation node dropped); the blocks of other types (``MASS``, ``SPRING2``,
    ``CONN3D2``, rigid ``R3D4`` ...) and blocks that name undefined nodes are counted as not
    drawn. Elements generated by ``*ELGEN``/``*ELCOPY`` are not read, so not drawn either.

    Parameters
    ----------
    model : InpModel

    Returns
    -------
    SurfaceElements
        Connectivity in :attr:`InpModel.node_ids`.
    """
    elements = SurfaceElements()
    for block in model.elements:
        labels = block.element_labels(model.scopes)
        if not labels.size:
            continue
        kind = surface_kind(block.type)
        scope, node_labels = block.node_labels(model.scopes)
        index = model.index_of(scope, node_labels)
        width = node_labels.size // labels.size
        need = SURFACE_ELEMENTS[kind] if kind is not None else 0
        lines = kind in ("line2", "line3")
        if kind is None or np.any(index < 0) or width < need or (width > need and not lines):
            elements.skip(block.type.upper(), labels.size)
            continue
        elements.add(kind, model.node_ids[index].reshape(labels.size, width)[:, :need])
    return elements


def _isotropic(material: Material) -> tuple[float, float] | str:
    """(E, nu) of a material, or why it is not an isotropic linear-elastic one."""
    where = f"{material.path.name}:{material.line}: material {material.name}"
    if material.elastic is None:
        return f"{where} has no *ELASTIC"
    if material.elastic_type != "ISOTROPIC":
        return f"{where} is elastic TYPE={material.elastic_type}; only ISOTROPIC is read"
    if len(material.elastic) != 1:
        return (
            f"{where}: *ELASTIC has {len(material.elastic)} data lines (temperature or field "
            "dependence); give one line E, nu"
        )
    fields = material.elastic[0]
    try:
        young, poisson = float(fields[0]), float(fields[1] if len(fields) > 1 else "0")
    except ValueError:
        return f"{where}: *ELASTIC data {', '.join(fields)} is not E, nu"
    if not (young > 0 and -1.0 < poisson < 0.5):
        return f"{where}: E = {young:g}, nu = {poisson:g} is not an elastic material"
    return young, poisson


def _element_sets(model: InpModel) -> dict[tuple[int, str], np.ndarray]:
    """Element labels of every set, keyed by (scope, upper-case name); later data adds to it."""
    members: dict[tuple[int, str], list[np.ndarray]] = {}
    for block in model.elements:
        if block.elset:
            key = (block.scope, block.elset.upper())
            members.setdefault(key, []).append(block.element_labels(model.scopes))
    return _set_members(members, model.elsets, "element label")


def node_sets(model: InpModel) -> dict[tuple[int, str], np.ndarray]:
    """Node labels of every node set, keyed by (scope, upper-case name).

    A set is the union of its ``*NSET`` data (labels, ``GENERATE`` ranges, names of sets defined
    before) and of the ``*NODE`` blocks that name it with ``NSET=``; later data adds to it.

    Raises
    ------
    UserError
        ``file:line: ...`` for a label that is not an integer or a malformed ``GENERATE`` line.
    """
    return _set_members({}, model.node_sets, "node label")


def named_node_sets(model: InpModel) -> dict[str, np.ndarray]:
    """The node ids of every node set (:func:`node_sets`), by upper-case name.

    A set of the model, of the assembly or of one instance keeps its name; a name that several
    scopes define (a part's set in each of its instances) becomes ``INSTANCE.NAME`` there, as
    Abaqus names a part's set from the assembly. Labels of no defined node are left out.
    """
    sets = node_sets(model)
    scopes_of: dict[str, int] = {}
    for _, name in sets:
        scopes_of[name] = scopes_of.get(name, 0) + 1
    out: dict[str, np.ndarray] = {}
    for (scope, name), labels in sets.items():
        index = model.index_of(np.full(labels.size, scope), labels)
        ids = model.node_ids[index[index >= 0]]
        key = name
        if scopes_of[name] > 1 and 0 <= scope < len(model.scopes):
            if model.scopes[scope].kind == "instance":
                key = f"{model.scopes[scope].name.upper()}.{name}"
        out[key] = sorted_unique(np.concatenate([out[key], ids])) if key in out else ids
    return out


def _set_members(
    members: dict[tuple[int, str], list[np.ndarray]], sets: tuple[ElementSet, ...], what: str
) -> dict[tuple[int, str], np.ndarray]:
    """``members`` with the labels of ``sets`` added, as arrays (see :func:`node_sets`)."""
    for entry in sets:
        key = (entry.scope, entry.name.upper())
        lists = members.setdefault(key, [])
        if entry.labels is not None:
            lists.append(entry.labels)
            continue
        for offset, line in enumerate(entry.text.split("\n")):
            text = line.split("**", 1)[0].strip()
            if not text:
                continue
            number = entry.first_line + offset
            fields = [f.strip() for f in text.split(",") if f.strip()]
            if entry.generate:
                values = [integer_field(entry.path, number, f, what) for f in fields]
                if len(values) not in (2, 3) or (len(values) == 3 and values[2] < 1):
                    raise located_error(
                        entry.path, number, "GENERATE data must be first, last[, step]"
                    )
                step = values[2] if len(values) == 3 else 1
                lists.append(np.arange(values[0], values[1] + 1, step, dtype=np.int64))
                continue
            for item in fields:
                if re.fullmatch(r"[+-]?\d+", item):
                    lists.append(np.array([integer_field(entry.path, number, item, "label")]))
                else:  # the name of another set of the scope
                    for part in members.get((entry.scope, item.upper()), []):
                        lists.append(part)
    return {
        key: np.concatenate(parts) if parts else np.zeros(0, np.int64)
        for key, parts in members.items()
    }


# ============================================================================ boundary conditions
#: The structural dofs 1-6 (ux uy uz rx ry rz) a *BOUNDARY line may name; others (11 temperature,
#: 8 pressure, ...) fix no displacement.
_STRUCTURAL_DOFS = 6


@dataclass(frozen=True, eq=False)
class BoundaryDofs:
    """The dofs fixed by ``*BOUNDARY`` blocks (:func:`boundary_dofs`), each once.

    Attributes
    ----------
    nodes : ndarray of int, shape (k,)
        Index in :attr:`InpModel.node_ids` of each fixed dof's node.
    directions : ndarray of int, shape (k,)
        Its direction, 0-5 (ux uy uz rx ry rz).
    lines : tuple of (Path, int)
        The file and line of every data line read.
    source : ndarray of int, shape (k,)
        Which entry of ``lines`` fixed each dof (the last one that did).
    """

    nodes: np.ndarray
    directions: np.ndarray
    lines: tuple[tuple[Path, int], ...]
    source: np.ndarray

    def where(self, k: int) -> str:
        """``file:line`` of the data line that fixed dof ``k``."""
        path, line = self.lines[int(self.source[k])]
        return f"{path.name}:{line}"


def boundary_dofs(model: InpModel, last_step: int | None = None) -> BoundaryDofs:
    """The displacement dofs that the ``*BOUNDARY`` blocks of the model fix.

    The blocks of the model data and of the steps up to ``last_step`` count (all steps by
    default); a block with ``OP=NEW`` removes those before it. Data lines are ``node or node
    set, first dof[, last dof[, value]]`` (dofs 1-6 = ux uy uz rx ry rz; a prescribed value
    fixes the dof too; dofs beyond 6, such as 11 for the temperature, are not displacements and
    are left out).

    Parameters
    ----------
    model : InpModel
    last_step : int, optional
        The last ``*STEP`` whose blocks count.

    Returns
    -------
    BoundaryDofs

    Raises
    ------
    UserError
        ``file:line: ...`` for an unknown node or node set, a dof that is not a number (an
        Abaqus type name such as ``ENCASTRE``) or out of order.
    """
    blocks = [b for b in model.boundaries if last_step is None or b.step <= last_step]
    sets: dict[tuple[int, str], np.ndarray] | None = None
    nodes: list[np.ndarray] = []
    directions: list[np.ndarray] = []
    sources: list[np.ndarray] = []
    where: list[tuple[Path, int]] = []
    for block in blocks:
        if block.new:
            nodes, directions, sources = [], [], []
        for offset, line in enumerate(block.text.split("\n")):
            text = line.split("**", 1)[0].strip()
            if not text:
                continue
            number = block.first_line + offset
            fields = [f.strip() for f in text.split(",")]
            if len(fields) < 2 or not fields[1]:
                raise located_error(
                    block.path, number, "*BOUNDARY data line needs: node or node set, first dof"
                )
            if not re.fullmatch(r"\d+", fields[1]):
                raise located_error(
                    block.path,
                    number,
                    f"*BOUNDARY dof {fields[1]!r} is not a dof number; give the dofs as numbers "
                    "(1-6 = ux uy uz rx ry rz), as CalculiX reads them",
                )
            first = integer_field(block.path, number, fields[1], "first dof", positive=True)
            last = first
            if len(fields) > 2 and fields[2]:
                last = integer_field(block.path, number, fields[2], "last dof", positive=True)
                if last < first:
                    raise located_error(
                        block.path, number, f"last dof {last} lies before the first dof {first}"
                    )
            last = min(last, _STRUCTURAL_DOFS)
            if first > last:
                continue  # a temperature or pressure dof
            if re.fullmatch(r"[+-]?\d+", fields[0]):
                label = integer_field(block.path, number, fields[0], "node label")
                index = model.index_of(np.array([block.scope]), np.array([label]))
                if index[0] < 0:
                    raise located_error(
                        block.path, number, f"*BOUNDARY names node {label}, which is not defined"
                    )
            else:
                if sets is None:
                    sets = node_sets(model)
                labels = sets.get((block.scope, fields[0].upper()))
                if labels is None:
                    raise located_error(
                        block.path,
                        number,
                        f"*BOUNDARY names node set {fields[0]}, which is not defined",
                    )
                index = model.index_of(np.full(labels.size, block.scope), labels)
                if np.any(index < 0):
                    missing = int(labels[np.flatnonzero(index < 0)[0]])
                    raise located_error(
                        block.path,
                        number,
                        f"node set {fields[0]} holds node {missing}, which is not defined",
                    )
            count = last - first + 1
            nodes.append(np.repeat(index, count))
            directions.append(np.tile(np.arange(first - 1, last), index.size))
            sources.append(np.full(index.size * count, len(where), dtype=np.int64))
            where.append((block.path, number))
    if not nodes:
        empty = np.zeros(0, dtype=np.int64)
        return BoundaryDofs(empty, empty, tuple(where), empty)
    node = np.concatenate(nodes)
    direction = np.concatenate(directions)
    source = np.concatenate(sources)
    key = node * _STRUCTURAL_DOFS + direction
    _, last_of = np.unique(key[::-1], return_index=True)  # the last line fixing each dof
    keep = np.sort(key.size - 1 - last_of)
    return BoundaryDofs(node[keep], direction[keep], tuple(where), source[keep])
