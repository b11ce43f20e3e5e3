"""The model the page works on: the opened body, its scene, its facts, picking and the view's
decorations of the job.

:class:`OpenedModel` holds one body at a time. Its scene (:func:`~pymorembs.report.body_scene`)
is what ``viewer.js`` draws; node *rows* are indices into the scene's nodes, the page's way of
naming nodes. The facts of ``pymorembs info`` (the lowest eigenfrequencies) are computed once
per body in a background thread, the centre of gravity once per body on demand.
"""

from __future__ import annotations

import threading
from typing import Any

import numpy as np

import pymorembs as pm
from pymorembs.body import ElasticBody
from pymorembs.errors import PymorembsError, UserError
from pymorembs.job.app.selection import free_node_id, hole_selection, selected_nodes
from pymorembs.job.schema import InterfaceNodeSpec, Job
from pymorembs.preparation import centre_of_gravity, select_nodes
from pymorembs.report import body_scene
from pymorembs.surface import smooth_patch

#: The facts of ``pymorembs info`` the page shows.
FACT_KEYS = (
    "name", "n_dof", "n_nodes", "n_independent", "n_dependent", "n_fixed", "rigid_body_modes",
    "eigenfrequencies_hz", "total_mass", "units",
)  # fmt: skip


class OpenedModel:
    """The opened body and what the page sees of it (none until :meth:`show`)."""

    def __init__(self) -> None:
        self.lock = threading.RLock()
        self.body: ElasticBody | None = None
        self.scene: dict[str, Any] | None = None
        self.scene_ids = np.zeros(0, dtype=np.int64)
        self._facts: dict[str, Any] | None = None
        self._facts_thread: threading.Thread | None = None
        self._cog: tuple[ElasticBody, np.ndarray] | None = None

    def show(self, body: ElasticBody) -> None:
        """Hold ``body`` and its scene; its facts are computed anew when asked for."""
        scene = body_scene(body)
        with self.lock:
            self.body = body
            self.scene = scene
            self.scene_ids = np.asarray(scene["node_ids"], dtype=np.int64)
            self._facts = None
            self._facts_thread = None

    def opened(self) -> ElasticBody:
        """The opened body.

        Raises
        ------
        UserError
            No model is open.
        """
        if self.body is None:
            raise UserError("no model is open")
        return self.body

    def summary(self) -> dict[str, Any] | None:
        """Name, dofs, nodes and whether it has a surface (None: no model open)."""
        body = self.body
        if body is None:
            return None
        return {
            "name": body.name,
            "n_dof": body.n_dof,
            "n_nodes": body.n_nodes,
            "surface": body.surface is not None,
        }

    def scene_json(self) -> dict[str, Any]:
        """The opened body for ``viewer.js`` (:func:`pymorembs.report.scene.body_scene`)."""
        self.opened()
        return self.scene

    def scene_rows(self, ids: np.ndarray) -> np.ndarray:
        """Indices into the scene's nodes of those of ``ids`` that the scene has."""
        scene = self.scene_ids
        if scene.size == 0:
            return np.zeros(0, dtype=np.int64)
        order = np.argsort(scene, kind="stable")
        ids = np.asarray(ids, dtype=np.int64)
        found = order[np.minimum(np.searchsorted(scene, ids, sorter=order), scene.size - 1)]
        return found[scene[found] == ids]

    # -- facts ----------------------------------------------------------------------------------
    def facts(self) -> dict[str, Any]:
        """The facts of ``pymorembs info`` (computed once per model, off the request thread)."""
        body = self.opened()
        with self.lock:
            if self._facts is None and self._facts_thread is None:
                self._facts_thread = threading.Thread(
                    target=self._compute_facts, args=(body,), daemon=True
                )
                self._facts_thread.start()
            thread = self._facts_thread
        if thread is not None:
            thread.join()
        with self.lock:
            return self._facts or {"error": "the model's facts could not be computed"}

    def _compute_facts(self, body: ElasticBody) -> None:
        try:
            facts = pm.facts(body, modes=10)
            out = {k: facts[k] for k in FACT_KEYS if k in facts}
        except PymorembsError as exc:
            out = {"error": " ".join(str(exc).split())}
        out["surface"] = None if body.surface is None else body.surface.source
        with self.lock:
            if self.body is body:
                self._facts = out

    def centre_of_gravity(self, body: ElasticBody) -> np.ndarray:
        """The centre of gravity of ``body`` (model length unit), computed once per body."""
        with self.lock:
            if self._cog is None or self._cog[0] is not body:
                self._cog = (body, centre_of_gravity(body))
            return self._cog[1]

    # -- picking --------------------------------------------------------------------------------
    def pick(self, request: dict[str, Any], taken: list[int] | tuple[int, ...] = ()) -> dict:
        """The smooth surface patch at a picked triangle (or node) and its job selection.

        Parameters
        ----------
        request : dict
            ``triangle`` (index into the surface's triangles) or ``node`` (a scene row), and
            ``max_angle_deg`` (the edge angle, default 30).
        taken : list of int
            Node ids the job's interfaces use (not proposed as the new node's id).
        """
        body = self.opened()
        surface = body.surface
        angle = float(request.get("max_angle_deg", 30.0))
        if surface is None or surface.triangles.shape[0] == 0:
            raise UserError("this model has no surface to pick on; give a cylinder or a box")
        if request.get("triangle") is not None:
            seed = int(request["triangle"])
        elif request.get("node") is not None:
            row = int(request["node"])
            if not 0 <= row < self.scene_ids.size:
                raise UserError(f"pick: no node {row} in the view (it has {self.scene_ids.size})")
            node = int(self.scene_ids[row])
            touching = np.flatnonzero((surface.triangles == node).any(axis=1))
            if touching.size == 0:
                raise UserError(f"node {node} is not on the surface")
            seed = int(touching[0])
        else:
            raise UserError("pick: give 'triangle' or 'node'")
        region = smooth_patch(surface, body.node_ids, body.coordinates, seed, angle)
        nodes = np.unique(surface.triangles[region])
        return {**self._selected(nodes, taken), **hole_selection(body, nodes)}

    def select(self, request: dict[str, Any], taken: list[int] | tuple[int, ...] = ()) -> dict:
        """Nodes of a selection given by numbers (as in ``[[interface]]``)."""
        return self._selected(selected_nodes(self.opened(), request), taken)

    def _selected(self, nodes: np.ndarray, taken: list[int] | tuple[int, ...]) -> dict[str, Any]:
        return {
            "count": int(nodes.size),
            "rows": self.scene_rows(nodes).tolist(),
            "ids": [int(n) for n in nodes],
            "free_id": free_node_id(self.opened(), taken),
        }

    # -- the job in the view --------------------------------------------------------------------
    def decorations(self, job: Job | None, draft: dict[str, Any]) -> dict[str, Any]:
        """What the 3D view draws of the job being edited (``viewer.setDecorations``).

        Parameters
        ----------
        job : Job or None
            The parsed job when it is valid: its interfaces and frame are drawn.
        draft : dict
            The page's job (read when ``job`` is None: what of it can be drawn is drawn).

        Returns
        -------
        dict
            ``frame``: ``{"origin": [3], "axes": [[3], [3], [3]]}`` (model length unit, the
            model's axes) or None: a tangent frame at its node (a node of the model or an
            interface node of the job, at its ``position``), a Buckens frame at the model's
            centre of gravity, none for ``type = "none"``; ``interfaces``: per ``[[interface]]``
            ``{"name", "node": index into the scene's nodes or None, "position": [3],
            "coupled": [indices into the scene's nodes]}``; ``notes``: what could not be drawn
            (a selection that gives no nodes, a frame node nobody has), one line each.
        """
        body = self.body
        out: dict[str, Any] = {"frame": None, "interfaces": [], "notes": []}
        if body is None:
            return out
        placed: dict[int, list[float]] = {}
        interfaces: Any = job.interfaces if job is not None else draft.get("interface") or []
        if not isinstance(interfaces, list | tuple):
            out["notes"].append("[[interface]] is not drawn: expected a list of tables")
            interfaces = []
        for k, item in enumerate(interfaces, start=1):
            try:
                node, position, kind, coupled = _interface(body, item)
            except (PymorembsError, KeyError, TypeError, ValueError) as exc:
                out["notes"].append(f"[[interface]] #{k} is not drawn: {_one_line(exc)}")
                continue
            row = self.scene_rows(np.array([node]))
            out["interfaces"].append({
                "name": f"interface {node} ({kind})",
                "node": int(row[0]) if row.size else None,
                "position": position,
                "coupled": self.scene_rows(coupled).tolist(),
            })  # fmt: skip
            placed[node] = position
        frame: Any = (draft.get("frame") or {}) if job is None else {}
        if not isinstance(frame, dict):
            out["notes"].append("[frame] is not drawn: it must be a table")
            frame = {}
        kind = job.frame.kind if job is not None else frame.get("type")
        origin = None
        try:
            if kind == "tangent":
                node = job.frame.node if job is not None else int(frame["node"])
                if node in placed:
                    origin = placed[node]
                elif node in body.node_index:
                    origin = body.node_position(node).tolist()
                else:
                    out["notes"].append(f"[frame] node {node} is neither a node of the model "
                                        "nor an interface node: no triad")  # fmt: skip
            elif kind == "buckens":
                origin = self.centre_of_gravity(body).tolist()
        except (PymorembsError, KeyError, TypeError, ValueError) as exc:
            out["notes"].append(f"[frame] is not drawn: {_one_line(exc)}")
        if origin is not None:
            out["frame"] = {"origin": origin, "axes": np.eye(3).tolist()}
        return out


def _interface(
    body: ElasticBody, item: InterfaceNodeSpec | Any
) -> tuple[int, list[float], str, np.ndarray]:
    """Node id, position, kind and coupled node ids of an ``[[interface]]``: a parsed one, or a
    table of the draft (raises KeyError, TypeError or ValueError where it is not written as
    the job writes it)."""
    if isinstance(item, InterfaceNodeSpec):
        coupled = select_nodes(body, ids=item.ids, cylinder=item.cylinder, box=item.box)
        return item.node, [float(x) for x in item.position], item.kind, coupled
    node = int(item["node"])
    position = [float(x) for x in item["position"]]
    if len(position) != 3 or not np.all(np.isfinite(position)):
        raise ValueError("position must be 3 finite numbers")
    return node, position, item.get("kind", "rigid"), selected_nodes(body, item)


def _one_line(exc: Exception) -> str:
    text = " ".join(str(exc).split())
    return f"missing {text}" if isinstance(exc, KeyError) else text
