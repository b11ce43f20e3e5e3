"""The file of a saved reduced body: ``ReducedBody.save(path)`` and ``pymorembs.load(path)``.

One HDF5 file, versioned, without pickles, that holds everything a
:class:`~pymorembs.api.ReducedBody` holds, so that a loaded body evaluates, exports and compares
exactly as the saved one: the prepared model (the body in its reference frame, the elimination
``q = T q_i + t``, the sparse system of the independent dofs with its ports, the inertia loads
and the geometric stiffening), the reduced model (the bases ``V`` and ``W``, the dense reduced
system, the eigenfrequencies, the method's parameters and error estimates), the model before
stiff directions were removed, the options and the name. Nothing is recomputed on load; what a
body computes on demand (the static response of ``to_vtu``) is computed again when asked for.

Layout (format version 1; ``n`` dofs of the body, ``n_i`` independent dofs, ``p``/``r`` port
inputs/outputs, ``k`` inertia loads, ``m`` the order). Matrices are float64, index arrays int64;
"CSR group" is a sparse matrix as ``data``, ``indices``, ``indptr`` and the attribute ``shape``
(as in :mod:`pymorembs.io.native`); texts are UTF-8 string datasets::

    /                         attributes format = "pymorembs-reduced-body", version = 1,
                              name, written_by ("pymorembs <version>")
    /options                  attribute method; string dataset values: JSON object of the options
                              that differ from their defaults
    /body                     the body in its reference frame, in the layout of
                              pymorembs.io.native (its own attributes format, version)
    /prepared                 attributes frame_kind ("tangent", "buckens", "none"; "" unknown),
                              frame_node (-1: none); string datasets warnings, notes
    /prepared/elimination     independent (n_i,), dependent, fixed; transform: CSR group (n, n_i);
                              offset (n,)
    /prepared/system          the system of the independent dofs, see "system" below (sparse)
    /prepared/inertia         optional: input_matrix (n_i, k), scales (k,); string datasets
                              cases, dropped
    /prepared/stiffening      optional: attribute source; string dataset case_names;
                              cases/<case>: CSR group (n_i, n_i); nodes/<j>: CSR group (n_i, n_i)
                              with attributes node, direction (0-5)
    /reduced                  the reduced model, see "model" below
    /before_removal           optional: the model before max_frequency_hz removed directions

    system:  mass, stiffness, damping (optional): CSR groups (prepared) or (m, m) arrays
             (reduced); input_matrix (n_i or m, p), output_matrix (r, n_i or m); string
             datasets input_labels, output_labels; static_load (optional); rigid_modes
             (optional, (n_i, 6), Buckens frame); attributes loss_factor, modal_damping_ratio;
             optional stress outputs: stress_matrix (CSR group (r_s, n_i) prepared, (r_s, m)
             array reduced), string dataset stress_labels, attributes stress_weight,
             stress_targeted
    model:   eigenfrequencies_hz (m,) in Hz; system/ (the reduced system: M = I, K diagonal or
             2x2 blocks, the inputs are the ports followed by the inertia loads);
             projection/V (n_i, m), projection/W (only for an oblique projection);
             projection/error_curve_hz, error_curve_estimate (optional); attributes method,
             one_sided, error_estimate and error_bound (NaN: none); string dataset parameters
             (JSON object)

Every array carries a Fletcher-32 checksum: a file damaged after it was written is refused.
Lengths, masses and times are in the FE model's units, frequencies in Hz.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import scipy.sparse as sp

from pymorembs.errors import UserError
from pymorembs.io.atomic import atomic_path
from pymorembs.io.native import (
    FLOAT_KINDS,
    INTEGER_KINDS,
    REDUCED_BODY_FORMAT,
    attribute_text,
    check_format_version,
    get_array,
    get_csr,
    put_array,
    put_csr,
    read_body_group,
    read_hdf5,
    write_body_group,
)
from pymorembs.io.native import FORMAT as BODY_FORMAT
from pymorembs.preparation import Frame, PreparedModel
from pymorembs.preparation.elimination import Elimination
from pymorembs.preparation.inertia_loads import InertiaLoads
from pymorembs.preparation.stiffening import Stiffening
from pymorembs.reduction.projection import Projection, ReducedModel
from pymorembs.system import SecondOrderSystem

__all__ = ["FORMAT", "VERSION", "SavedBody", "read_reduced_body", "write_reduced_body"]

#: Value of the root attribute ``format``.
FORMAT = REDUCED_BODY_FORMAT
#: Format version written (and the newest one read).
VERSION = 1


@dataclass(frozen=True, eq=False)
class SavedBody:
    """The parts of a reduced body as the file holds them.

    Attributes
    ----------
    prepared : PreparedModel
    model : ReducedModel
    method : str
        The reduction method.
    options : dict
        The method's options that differ from their defaults (``ReductionOptions.given()``).
    name : str
    before_removal : ReducedModel or None
    """

    prepared: PreparedModel
    model: ReducedModel
    method: str
    options: dict[str, Any]
    name: str
    before_removal: ReducedModel | None = None


def write_reduced_body(path: str | os.PathLike[str], saved: SavedBody) -> Path:
    """Write a reduced body to the HDF5 file ``path`` (atomically; layout in the module
    docstring). Returns ``path``."""
    from pymorembs import __version__  # the package imports this module

    path = Path(path)
    with atomic_path(path) as tmp, h5py.File(tmp, "w") as f:
        f.attrs["format"] = FORMAT
        f.attrs["version"] = VERSION
        f.attrs["name"] = str(saved.name)
        f.attrs["written_by"] = f"pymorembs {__version__}"
        options = f.create_group("options")
        options.attrs["method"] = saved.method
        _put_json(options, "values", saved.options)
        write_body_group(f.create_group("body"), saved.prepared.body)
        _put_prepared(f.create_group("prepared"), saved.prepared)
        _put_model(f.create_group("reduced"), saved.model)
        if saved.before_removal is not None:
            _put_model(f.create_group("before_removal"), saved.before_removal)
    return path


def read_reduced_body(path: str | os.PathLike[str]) -> SavedBody:
    """Read a reduced body written by :func:`write_reduced_body`.

    Raises
    ------
    UserError
        One line naming the file: missing, not HDF5, another kind of file (an FE model points
        to ``pymorembs.read``), a newer format version, a missing or inconsistent part (named by
        its HDF5 path), or damaged (truncated, a checksum that does not match).
    """
    return read_hdf5(path, _read_saved, "a reduced body saved by ReducedBody.save", "the body")


# ------------------------------------------------------------------------------------- writing
def _put_texts(group: h5py.Group, key: str, texts: tuple[str, ...] | list[str]) -> None:
    group.create_dataset(key, data=[str(t) for t in texts], dtype=h5py.string_dtype())


def _put_json(group: h5py.Group, key: str, value: dict[str, Any]) -> None:
    group.create_dataset(key, data=json.dumps(value, default=_plain), dtype=h5py.string_dtype())


def _plain(value: Any) -> Any:
    """NumPy values as JSON can hold them (for :func:`json.dumps`)."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"{type(value).__name__} cannot be saved in a reduced body file")


def _put_matrix(group: h5py.Group, key: str, matrix: Any) -> None:
    if sp.issparse(matrix):
        put_csr(group, key, matrix)
    else:
        put_array(group, key, np.asarray(matrix), np.float64)


def _put_system(group: h5py.Group, system: SecondOrderSystem) -> None:
    for key in ("mass", "stiffness", "damping"):
        if getattr(system, key) is not None:
            _put_matrix(group, key, getattr(system, key))
    put_array(group, "input_matrix", system.input_matrix, np.float64)
    put_array(group, "output_matrix", system.output_matrix, np.float64)
    _put_texts(group, "input_labels", system.input_labels)
    _put_texts(group, "output_labels", system.output_labels)
    for key in ("static_load", "rigid_modes"):
        if getattr(system, key) is not None:
            put_array(group, key, getattr(system, key), np.float64)
    group.attrs["loss_factor"] = float(system.loss_factor)
    group.attrs["modal_damping_ratio"] = float(system.modal_damping_ratio)
    if system.stress_matrix is not None:
        _put_matrix(group, "stress_matrix", system.stress_matrix)
        _put_texts(group, "stress_labels", system.stress_labels)
        group.attrs["stress_weight"] = float(system.stress_weight)
        group.attrs["stress_targeted"] = bool(system.stress_targeted)


def _put_prepared(group: h5py.Group, prepared: PreparedModel) -> None:
    frame = prepared.frame
    group.attrs["frame_kind"] = "" if frame is None else frame.kind.value  # a plain str
    group.attrs["frame_node"] = -1 if frame is None or frame.node is None else int(frame.node)
    _put_texts(group, "warnings", prepared.warnings)
    _put_texts(group, "notes", prepared.notes)
    elimination = group.create_group("elimination")
    for key in ("independent", "dependent", "fixed"):
        put_array(elimination, key, getattr(prepared.elimination, key), np.int64)
    put_csr(elimination, "transform", prepared.elimination.transform)
    put_array(elimination, "offset", prepared.elimination.offset, np.float64)
    _put_system(group.create_group("system"), prepared.system)
    if prepared.inertia is not None:
        inertia = group.create_group("inertia")
        put_array(inertia, "input_matrix", prepared.inertia.input_matrix, np.float64)
        put_array(inertia, "scales", prepared.inertia.scales, np.float64)
        _put_texts(inertia, "cases", prepared.inertia.cases)
        _put_texts(inertia, "dropped", prepared.inertia.dropped)
    if prepared.stiffening is not None:
        stiffening = group.create_group("stiffening")
        stiffening.attrs["source"] = prepared.stiffening.source
        _put_texts(stiffening, "case_names", list(prepared.stiffening.cases))
        for case, matrix in prepared.stiffening.cases.items():
            put_csr(stiffening, f"cases/{case}", matrix)
        for j, ((node, direction), matrix) in enumerate(prepared.stiffening.nodes.items()):
            put_csr(stiffening, f"nodes/{j}", matrix)
            stiffening[f"nodes/{j}"].attrs["node"] = int(node)
            stiffening[f"nodes/{j}"].attrs["direction"] = int(direction)


def _put_model(group: h5py.Group, model: ReducedModel) -> None:
    put_array(group, "eigenfrequencies_hz", model.eigenfrequencies_hz, np.float64)
    _put_system(group.create_group("system"), model.system)
    projection = model.projection
    out = group.create_group("projection")
    put_array(out, "V", projection.V, np.float64)
    if not projection.one_sided:
        put_array(out, "W", projection.W, np.float64)
    out.attrs["method"] = projection.method
    out.attrs["one_sided"] = bool(projection.one_sided)
    for key in ("error_estimate", "error_bound"):
        value = getattr(projection, key)
        out.attrs[key] = np.nan if value is None else float(value)
    _put_json(out, "parameters", dict(projection.parameters))
    if projection.error_curve is not None:
        put_array(out, "error_curve_hz", projection.error_curve[0], np.float64)
        put_array(out, "error_curve_estimate", projection.error_curve[1], np.float64)


# ------------------------------------------------------------------------------------- reading
def _read_saved(f: h5py.File) -> SavedBody:
    """Check the format marker and version and build the parts from an open file."""
    marker = attribute_text(f.attrs.get("format"))
    if marker == BODY_FORMAT:
        raise UserError(
            "an FE model (a pymorembs body file), not a saved reduced body; read it with "
            "pymorembs.read(path)"
        )
    if marker != FORMAT:
        raise UserError(
            f"HDF5 file without the format marker {FORMAT!r}; not a reduced body saved by "
            "ReducedBody.save"
        )
    check_format_version(f, VERSION)
    options = _group(f, "options")
    values = _json(options, "values")
    prepared = _read_prepared(f)
    system = prepared.reduction_system
    model = _read_model(_group(f, "reduced"), system)
    before = _read_model(_group(f, "before_removal"), system) if "before_removal" in f else None
    return SavedBody(
        prepared,
        model,
        attribute_text(options.attrs.get("method")),
        values,
        attribute_text(f.attrs.get("name", "body")),
        before,
    )


def _group(f: h5py.Group, key: str) -> h5py.Group:
    node = f.get(key)
    if not isinstance(node, h5py.Group):
        raise UserError(f"/{_name(f, key)} is missing")
    return node


def _name(group: h5py.Group, key: str) -> str:
    return f"{group.name.strip('/')}/{key}".strip("/")


def _texts(group: h5py.Group, key: str) -> tuple[str, ...]:
    node = group.get(key)
    if not isinstance(node, h5py.Dataset) or node.ndim != 1 or node.dtype.kind not in "OS":
        raise UserError(f"/{_name(group, key)} is missing or not a list of texts")
    return tuple(attribute_text(text) for text in node[()])


def _json(group: h5py.Group, key: str) -> dict[str, Any]:
    node = group.get(key)
    if not isinstance(node, h5py.Dataset) or node.ndim != 0:
        raise UserError(f"/{_name(group, key)} is missing or not a text")
    try:
        value = json.loads(attribute_text(node[()]))
    except json.JSONDecodeError as exc:
        raise UserError(f"/{_name(group, key)} is not JSON ({exc.msg})") from None
    if not isinstance(value, dict):
        raise UserError(f"/{_name(group, key)} is not a JSON object")
    return value


def _shaped(group: h5py.Group, key: str, shape: tuple[int | None, ...]) -> np.ndarray:
    """A float array of this shape (None: any length along that axis)."""
    values = get_array(group, key, FLOAT_KINDS, ndim=len(shape))
    if any(want is not None and got != want for got, want in zip(values.shape, shape, strict=True)):
        wanted = "(" + ", ".join("any" if s is None else str(s) for s in shape) + ")"
        raise UserError(f"/{_name(group, key)} has shape {values.shape}, expected {wanted}")
    return values


def _matrix(group: h5py.Group, key: str, n: int) -> Any:
    """An (n, n) matrix stored as a CSR group or an array."""
    if isinstance(group.get(key), h5py.Group):
        matrix = get_csr(group, key, n)
        if matrix.shape[0] != n:
            raise UserError(f"/{_name(group, key)} has shape {matrix.shape}, expected ({n}, {n})")
        return matrix
    return _shaped(group, key, (n, n))


def _read_system(group: h5py.Group, n: int) -> SecondOrderSystem:
    inputs = _shaped(group, "input_matrix", (n, None))
    outputs = _shaped(group, "output_matrix", (None, n))
    input_labels, output_labels = _texts(group, "input_labels"), _texts(group, "output_labels")
    if len(input_labels) != inputs.shape[1] or len(output_labels) != outputs.shape[0]:
        raise UserError(
            f"/{group.name.strip('/')}: {len(input_labels)} input and {len(output_labels)} output "
            f"labels for {inputs.shape[1]} inputs and {outputs.shape[0]} outputs"
        )
    return SecondOrderSystem(
        mass=_matrix(group, "mass", n),
        stiffness=_matrix(group, "stiffness", n),
        damping=_matrix(group, "damping", n) if "damping" in group else None,
        input_matrix=inputs,
        output_matrix=outputs,
        loss_factor=float(group.attrs.get("loss_factor", 0.0)),
        modal_damping_ratio=float(group.attrs.get("modal_damping_ratio", 0.0)),
        input_labels=input_labels,
        output_labels=output_labels,
        static_load=_shaped(group, "static_load", (n,)) if "static_load" in group else None,
        rigid_modes=_shaped(group, "rigid_modes", (n, None)) if "rigid_modes" in group else None,
        **_stress_outputs(group, n),
    )


def _stress_outputs(group: h5py.Group, n: int) -> dict[str, Any]:
    """The stress outputs of a saved system as keywords of :class:`SecondOrderSystem` (none
    when it has none)."""
    if "stress_matrix" not in group:
        return {}
    if isinstance(group.get("stress_matrix"), h5py.Group):
        matrix = get_csr(group, "stress_matrix", n)
    else:
        matrix = _shaped(group, "stress_matrix", (None, n))
    labels = _texts(group, "stress_labels")
    if len(labels) != matrix.shape[0]:
        raise UserError(f"/{group.name.strip('/')}: {len(labels)} stress labels for "
                        f"{matrix.shape[0]} stress outputs")  # fmt: skip
    return {
        "stress_matrix": matrix,
        "stress_labels": labels,
        "stress_weight": float(group.attrs.get("stress_weight", 1.0)),
        "stress_targeted": bool(group.attrs.get("stress_targeted", False)),
    }


def _read_prepared(f: h5py.File) -> PreparedModel:
    body = read_body_group(_group(f, "body"))
    group = _group(f, "prepared")
    part = _group(group, "elimination")
    families = [get_array(part, key, INTEGER_KINDS) for key in ("independent", "dependent",
                                                                 "fixed")]  # fmt: skip
    every = np.sort(np.concatenate(families))
    if every.size != body.n_dof or not np.array_equal(every, np.arange(body.n_dof)):
        raise UserError(
            f"/{part.name.strip('/')}: independent, dependent and fixed dofs do not split the "
            f"{body.n_dof} dofs of the body"
        )
    n_i = families[0].size
    transform = get_csr(part, "transform", n_i)
    if transform.shape[0] != body.n_dof:
        raise UserError(f"/{_name(part, 'transform')} has {transform.shape[0]} rows, expected "
                        f"{body.n_dof}")  # fmt: skip
    elimination = Elimination(*families, transform, _shaped(part, "offset", (body.n_dof,)))
    system = _read_system(_group(group, "system"), n_i)
    inertia = None
    if "inertia" in group:
        part = _group(group, "inertia")
        cases = _texts(part, "cases")
        inertia = InertiaLoads(
            cases,
            _shaped(part, "input_matrix", (n_i, len(cases))),
            _shaped(part, "scales", (len(cases),)),
            _texts(part, "dropped"),
        )
    stiffening = None
    if "stiffening" in group:
        part = _group(group, "stiffening")
        cases = {case: _matrix(part, f"cases/{case}", n_i) for case in _texts(part, "case_names")}
        nodes = {}
        for key in sorted(part.get("nodes", {}), key=int):
            attrs = part[f"nodes/{key}"].attrs
            nodes[(int(attrs["node"]), int(attrs["direction"]))] = _matrix(part, f"nodes/{key}",
                                                                           n_i)  # fmt: skip
        stiffening = Stiffening(attribute_text(part.attrs.get("source")), cases, nodes)
    kind = attribute_text(group.attrs.get("frame_kind", ""))
    if kind not in ("tangent", "buckens", "none", ""):
        raise UserError(f"/prepared: unknown frame_kind {kind!r}")
    node = int(group.attrs.get("frame_node", -1))
    frame = Frame(kind, None if node == -1 else node) if kind else None
    return PreparedModel(
        body,
        elimination,
        system,
        _texts(group, "warnings"),
        inertia,
        stiffening,
        frame,
        _texts(group, "notes"),
    )


def _read_model(group: h5py.Group, full: SecondOrderSystem) -> ReducedModel:
    part = _group(group, "projection")
    v = _shaped(part, "V", (full.order, None))
    order = v.shape[1]
    one_sided = bool(part.attrs.get("one_sided", True))
    w = v if one_sided else _shaped(part, "W", (full.order, order))
    curve = None
    if "error_curve_hz" in part:
        hz = get_array(part, "error_curve_hz", FLOAT_KINDS)
        curve = (hz, _shaped(part, "error_curve_estimate", (hz.size,)))
    estimate, bound = (float(part.attrs.get(key, np.nan)) for key in ("error_estimate",
                                                                       "error_bound"))  # fmt: skip
    projection = Projection(
        v,
        w,
        attribute_text(part.attrs.get("method")),
        _json(part, "parameters"),
        None if np.isnan(estimate) else estimate,
        None if np.isnan(bound) else bound,
        curve,
    )
    system = _read_system(_group(group, "system"), order)
    if (system.input_labels, system.output_labels) != (full.input_labels, full.output_labels):
        raise UserError(
            f"/{group.name.strip('/')}/system: its inputs and outputs are not those of the "
            "prepared model"
        )
    frequencies = _shaped(group, "eigenfrequencies_hz", (order,))
    return ReducedModel(projection, system, frequencies)
