"""Which consistent unit system an FE model is in, guessed from its numbers.

FE programs have no units: the model is consistent in whatever system its author chose, and
pymorembs' frequencies are in 1/(the model's time unit). A model in mm-kg-ms-kN therefore has its
eigenfrequencies in kHz, and a job band of ``f_max_hz = 1000`` means 1000 kHz there. This module
states the system the numbers point to, so that the summary and ``pymorembs info`` can say it and
contradictions can be warned about.

Two numbers decide, both computed in O(n_nodes log n_nodes + n_dof):

``implied_density``
    total mass / volume of the bounding box of the nodes along their principal axes (mass per
    length^3). A body fills part of its box (the rack: 9 % to 50 %), so the accepted range spans
    fill factors of about 0.001 to 1 and materials from foams to tungsten. Nodes on a line (a
    beam model) or in a plane (a shell model) span no volume: the box gets the section of the
    beams or the thickness of the shell from the rotary inertia of the nodes (radius of
    gyration), else a section of the node spacing (a line) or a thickness of 1 % of the size.
``implied_wave_speed_squared``
    ``median(k_ii / m_ii) * h^2`` over translational dofs with mass, ``h`` the median distance
    of a node to its nearest neighbour (length^2 / time^2). For an element of size ``h`` the
    ratio of diagonal stiffness to diagonal mass is ``~ c^2 / h^2`` with ``c^2 = E / rho`` (the
    bar wave speed squared) times a factor of order 1 to 30 that depends on the element.

In SI the rack gives 680 to 3300 kg/m^3 (steel 7850 in a box it fills partly) and 7.7e7 to 5.9e8
m^2/s^2 (steel: E/rho = 2.7e7). Every other system scales both numbers by fixed factors
(:data:`SYSTEMS`), so the guess is the system whose expected (log density, log c^2) lies
nearest; it is ``plausible`` when both numbers fall in that system's ranges, ``ambiguous`` when
a second system's ranges hold them too.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import scipy.sparse as sp

from pymorembs.body import ConstraintEquations, ElasticBody


@dataclass(frozen=True)
class UnitSystem:
    """A consistent unit system of FE models.

    Attributes
    ----------
    name : str
        E.g. ``"m-kg-s-N"``.
    length, mass, time, force : str
        The base units.
    length_m, mass_kg, time_s : float
        Their size in SI (1 mm = 1e-3 m).
    """

    name: str
    length: str
    mass: str
    time: str
    force: str
    length_m: float
    mass_kg: float
    time_s: float

    @property
    def density_factor(self) -> float:
        """A density of 1 kg/m^3 in this system's mass / length^3."""
        return self.length_m**3 / self.mass_kg

    @property
    def speed_squared_factor(self) -> float:
        """A speed squared of 1 m^2/s^2 in this system's length^2 / time^2."""
        return (self.time_s / self.length_m) ** 2

    @property
    def frequency_unit(self) -> str:
        """What pymorembs' "Hz" mean for a model in this system."""
        return {"s": "Hz", "ms": "kHz"}.get(self.time, f"1/{self.time}")


#: The usual consistent systems of FE models.
SYSTEMS: tuple[UnitSystem, ...] = (
    UnitSystem("m-kg-s-N", "m", "kg", "s", "N", 1.0, 1.0, 1.0),
    UnitSystem("mm-t-s-N", "mm", "t", "s", "N", 1e-3, 1e3, 1.0),
    UnitSystem("mm-kg-ms-kN", "mm", "kg", "ms", "kN", 1e-3, 1.0, 1e-3),
    UnitSystem("cm-g-s-dyn", "cm", "g", "s", "dyn", 1e-2, 1e-3, 1.0),
    UnitSystem("in-lbf-s", "in", "lbf s^2/in", "s", "lbf", 0.0254, 175.126836, 1.0),
)
#: Accepted implied density in SI, kg/m^3: fill factor 0.001-1 of materials of 300-20,000 kg/m^3
#: (below 3: only very sparse frames of light materials).
DENSITY_RANGE_SI = (3.0, 3e4)
#: Accepted implied wave speed squared in SI, m^2/s^2 (rubber-like 1e3 up to ceramics 1e8, times
#: an element factor up to 100).
SPEED_SQUARED_RANGE_SI = (1e3, 1e10)
#: Expected values in SI (the logarithmic centre of the rack models and common metals).
DENSITY_TYPICAL_SI = 1500.0
SPEED_SQUARED_TYPICAL_SI = 1e8


#: A material's density in SI, kg/m^3, as mass / volume of its solid elements: from foams and
#: balsa (100) down by a factor 2, up to osmium (22,600) with non-structural mass on top (x 4).
MATERIAL_DENSITY_RANGE_SI = (50.0, 1e5)
#: A material's ``E / rho`` in SI, m^2/s^2: soft rubber (1e6 Pa / 1100 kg/m^3 ~ 900) with added
#: mass, down to 100; diamond (1.05e12 / 3500 = 3e8) up to 1e9.
MATERIAL_SPEED_SQUARED_RANGE_SI = (1e2, 1e9)
#: Length units by name and size in m, for messages about coordinates in another unit.
LENGTH_UNITS = {"mm": 1e-3, "cm": 1e-2, "dm": 0.1, "m": 1.0, "in": 0.0254, "ft": 0.3048}
#: Factors by which coordinates are tried against the matrices when their unit looks wrong
#: (between the lengths of :data:`LENGTH_UNITS`: mm <-> m, cm <-> m, mm <-> cm, in <-> m, ...).
COORDINATE_SCALES = (1e-3, 1e3, 1e-2, 1e2, 1e-1, 1e1, 0.0254, 1 / 0.0254, 25.4, 1 / 25.4)


def length_unit_name(length_m: float) -> str:
    """The name of a length of ``length_m`` metres (``"mm"``), or ``"<x> m"`` if it has none."""
    for name, size in LENGTH_UNITS.items():
        if abs(length_m / size - 1.0) < 1e-6:
            return name
    return f"{length_m:.4g} m"


def material_systems(density: float, speed_squared: float) -> list[UnitSystem]:
    """The systems of :data:`SYSTEMS` in which a material is plausible.

    Parameters
    ----------
    density : float
        Mass / volume of the solid elements, model units (mass / length^3).
    speed_squared : float
        Young's modulus / density, model units (length^2 / time^2).

    Returns
    -------
    list of UnitSystem
        Those whose :data:`MATERIAL_DENSITY_RANGE_SI` and :data:`MATERIAL_SPEED_SQUARED_RANGE_SI`
        hold both numbers (empty: no consistent system has such a material).
    """
    out = []
    for system in SYSTEMS:
        rho = density / system.density_factor
        c2 = speed_squared / system.speed_squared_factor
        if (
            MATERIAL_DENSITY_RANGE_SI[0] <= rho <= MATERIAL_DENSITY_RANGE_SI[1]
            and MATERIAL_SPEED_SQUARED_RANGE_SI[0] <= c2 <= MATERIAL_SPEED_SQUARED_RANGE_SI[1]
        ):
            out.append(system)
    return out


@dataclass(frozen=True)
class UnitGuess:
    """The unit system a model's numbers point to.

    Attributes
    ----------
    system : UnitSystem or None
        The nearest system (None when the model gives nothing to judge: no mass, one node).
    plausible : bool
        Both numbers lie in the ranges of ``system``.
    ambiguous : tuple of str
        Other systems whose ranges hold the numbers too.
    implied_density : float
        Total mass / bounding-box volume, model units (nan if not available).
    implied_wave_speed_squared : float
        See the module docstring, model units (nan if not available).
    warnings : tuple of str
        One line each: implausible numbers.
    reason : str
        Why ``system`` is None (for :meth:`describe`).
    """

    system: UnitSystem | None
    plausible: bool
    ambiguous: tuple[str, ...] = ()
    implied_density: float = float("nan")
    implied_wave_speed_squared: float = float("nan")
    warnings: tuple[str, ...] = field(default=())
    reason: str = "no mass or fewer than two nodes"

    @property
    def name(self) -> str:
        """The system's name, or ``"unknown"``."""
        return self.system.name if self.system is not None else "unknown"

    def describe(self) -> str:
        """One line for ``pymorembs info``."""
        if self.system is None:
            return f"unknown ({self.reason})"
        s = self.system
        text = f"{s.name} ({s.length}, {s.mass}, {s.time}, {s.force}; frequencies in "
        text += f"{s.frequency_unit})"
        if not self.plausible:
            text += ", implausible numbers"
        elif self.ambiguous:
            text += f", also possible: {', '.join(self.ambiguous)}"
        return text

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready (for ``summary.json``)."""
        s = self.system

        def finite(x: float) -> float | None:
            return float(x) if np.isfinite(x) else None

        return {
            "system": self.name,
            "length": s.length if s else None,
            "mass": s.mass if s else None,
            "time": s.time if s else None,
            "force": s.force if s else None,
            "frequency_unit": s.frequency_unit if s else None,
            "plausible": bool(self.plausible),
            "also_possible": list(self.ambiguous),
            "implied_density": finite(self.implied_density),
            "implied_wave_speed_squared": finite(self.implied_wave_speed_squared),
            "method": "total mass / bounding-box volume, median(k_ii/m_ii) * h^2",
        }


def implied_numbers(body: ElasticBody) -> tuple[float, float]:
    """``(implied_density, implied_wave_speed_squared)`` of a body, model units (see module).

    NaN where the body gives nothing to judge (no mass, fewer than two distinct nodes).
    """
    from scipy.spatial import cKDTree

    coordinates = body.coordinates
    if coordinates.shape[0] < 2:
        return float("nan"), float("nan")
    extent, axes = _principal_box(coordinates)
    largest = float(extent[0])
    if largest <= 0:
        return float("nan"), float("nan")
    distance, _ = cKDTree(coordinates).query(coordinates, k=2)
    spacing = distance[:, 1][distance[:, 1] > 0]
    h = float(np.median(spacing)) if spacing.size else 0.0
    # nodes on a line (beams) or in a plane (shells) span no volume: a section or thickness
    # from the rotary inertia of the nodes, else the node spacing (a line) or 1 % of the size
    floor = 1e-2 * largest
    thin = max(floor, h)
    sizes = np.maximum(extent, floor)
    if extent[1] < thin:  # a line: the section of its beams from the rotary inertia about it
        r2 = _rotary_radius_squared(body, axes[:1])
        sizes[1:] = np.maximum(extent[1:], thin if r2 is None else np.sqrt(6.0 * r2))
    elif extent[2] < thin:  # a plane: the thickness of a shell, r^2 = t^2 / 12 in-plane
        r2 = _rotary_radius_squared(body, axes[:2])
        if r2 is not None:
            sizes[2] = max(extent[2], np.sqrt(12.0 * r2))
    volume = float(np.prod(sizes))
    mass = body.total_mass()
    density = mass / volume if mass > 0 else float("nan")
    k_diag, m_diag = body.stiffness.diagonal(), body.mass.diagonal()
    use = (body.dofs.directions < 3) & (m_diag > 0) & (k_diag > 0)
    if spacing.size == 0 or not np.any(use):
        return density, float("nan")
    return density, float(np.median(k_diag[use] / m_diag[use])) * h * h


def _principal_box(coordinates: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Sizes of the box of the points along their principal axes, descending, and the axes
    (rows); thin for an inclined line or plane of nodes, unlike the box along x, y, z."""
    centred = coordinates - coordinates.mean(axis=0)
    _, _, axes = np.linalg.svd(centred, full_matrices=False)  # (n, 3) points: cheap
    along = centred @ axes.T
    extent = along.max(axis=0) - along.min(axis=0)
    return np.concatenate([extent, np.zeros(3 - extent.size)]), axes


def _rotary_radius_squared(body: ElasticBody, axes: np.ndarray) -> float | None:
    """Squared radius of gyration of the nodes' rotary mass about ``axes`` (rows, unit).

    The median over the nodes with all six dofs of ``mean_a(a^T R a) / m``, ``R`` a node's
    3 x 3 block of rotary mass and ``m`` its mean translational mass diagonal. A line of beams
    (about its axis: ``rho Ip`` per length against ``rho A``) has ``r^2 = Ip / A``, ``s^2 / 6``
    for a square of side ``s``; a shell (about in-plane axes: ``rho t^3 / 12`` against
    ``rho t``) ``t^2 / 12``. None without rotational dofs with mass.
    """
    m_diag = body.mass.diagonal()
    nodes = np.unique(body.dofs.nodes)
    translation = body.dofs.positions(nodes[:, None], np.arange(3)[None, :])
    rotation = body.dofs.positions(nodes[:, None], np.arange(3, 6)[None, :])
    full = np.all(translation >= 0, axis=1) & np.all(rotation >= 0, axis=1)
    if not np.any(full):
        return None
    moved = m_diag[translation[full]].mean(axis=1)
    rows = rotation[full]
    mass = sp.csr_matrix(body.mass)
    turned = np.zeros(rows.shape[0])
    for a in range(3):
        for b in range(3):
            block = np.asarray(mass[rows[:, a], rows[:, b]]).ravel()
            turned += (axes[:, a] @ axes[:, b]) / len(axes) * block
    use = (moved > 0) & (turned > 0)
    if not np.any(use):
        return None
    return float(np.median(turned[use] / moved[use]))


def _ranges(system: UnitSystem) -> tuple[tuple[float, float], tuple[float, float]]:
    rho = tuple(np.log10(np.asarray(DENSITY_RANGE_SI) * system.density_factor))
    c2 = tuple(np.log10(np.asarray(SPEED_SQUARED_RANGE_SI) * system.speed_squared_factor))
    return rho, c2  # type: ignore[return-value]


def detect_units(body: ElasticBody) -> UnitGuess:
    """Guess the unit system of ``body`` from its implied density and wave speed.

    Returns
    -------
    UnitGuess
        The nearest system in (log density, log c^2), normalised by the half-widths of the
        ranges; ``warnings`` holds one line if no system's ranges hold the numbers.
    """
    if not body.has_coordinates:
        return UnitGuess(None, False, reason="no coordinates: units cannot be judged")
    return units_of_numbers(*implied_numbers(body))


def units_of_numbers(density: float, speed2: float) -> UnitGuess:
    """:func:`detect_units` from the two implied numbers (model units): the nearest system.

    Coordinates scaled by ``s`` scale the numbers by ``s^-3`` and ``s^2``, so a guess for
    coordinates in another length unit needs no new pass over the model.
    """
    if not np.isfinite(density):
        return UnitGuess(None, False, (), density, speed2)
    log_rho = np.log10(density)
    log_c2 = np.log10(speed2) if np.isfinite(speed2) and speed2 > 0 else None
    half_rho = 0.5 * np.log10(DENSITY_RANGE_SI[1] / DENSITY_RANGE_SI[0])
    half_c2 = 0.5 * np.log10(SPEED_SQUARED_RANGE_SI[1] / SPEED_SQUARED_RANGE_SI[0])
    scores, inside = [], []
    for system in SYSTEMS:
        centre_rho = np.log10(DENSITY_TYPICAL_SI * system.density_factor)
        score = ((log_rho - centre_rho) / half_rho) ** 2
        (rho_lo, rho_hi), (c2_lo, c2_hi) = _ranges(system)
        ok = rho_lo <= log_rho <= rho_hi
        if log_c2 is not None:
            centre_c2 = np.log10(SPEED_SQUARED_TYPICAL_SI * system.speed_squared_factor)
            score += ((log_c2 - centre_c2) / half_c2) ** 2
            ok = ok and c2_lo <= log_c2 <= c2_hi
        scores.append(score)
        inside.append(ok)
    best = int(np.argmin(scores))
    system = SYSTEMS[best]
    others = tuple(s.name for s, ok in zip(SYSTEMS, inside, strict=True) if ok and s != system)
    warnings: tuple[str, ...] = ()
    if not inside[best]:
        warnings = (
            f"the model's numbers fit no usual unit system (mass / bounding-box volume "
            f"{density:.3g}, wave speed^2 estimate {speed2:.3g}); nearest: {system.name}. "
            "Check the units of the mass and stiffness matrices and the coordinates",
        )
    return UnitGuess(system, bool(inside[best]), others, float(density), float(speed2), warnings)


def frequency_warnings(
    guess: UnitGuess, band_hz: tuple[float, float], eigenfrequencies_hz: np.ndarray
) -> list[str]:
    """Contradictions between the job's band and the model's eigenfrequencies (one line each).

    Parameters
    ----------
    guess : UnitGuess
    band_hz : (float, float)
        The job's band, in 1/(model time unit).
    eigenfrequencies_hz : ndarray
        Eigenfrequencies known so far (e.g. of the reduced models), same unit; zeros (rigid-body
        modes) are ignored.
    """
    values = np.asarray(eigenfrequencies_hz, dtype=float)
    values = values[np.isfinite(values) & (values > 0)]
    warnings = []
    unit = ""
    if guess.system is not None and guess.system.time != "s":
        unit = (
            f" (the model looks like {guess.system.name}: its frequencies are in "
            f"{guess.system.frequency_unit})"
        )
    if values.size and band_hz[1] > 100 * values.max():
        warnings.append(
            f"the band reaches {band_hz[1]:g} Hz, more than 100 times every eigenfrequency "
            f"computed (highest {values.max():.3g} Hz){unit}; check the band and the units"
        )
    if values.size and band_hz[1] < values.min() / 100:
        warnings.append(
            f"the band ends at {band_hz[1]:g} Hz, below 1/100 of the lowest eigenfrequency "
            f"({values.min():.3g} Hz){unit}; check the band and the units"
        )
    if not warnings and unit:
        warnings.append(f"frequencies are in 1/{guess.system.time}{unit}; the band is in that unit")
    return warnings


#: ``f / 2 pi`` this close (relative) to a round number makes a band look like rad/s: four or
#: more digits of 2 pi (6283, 628.3, 314.16), not a rounded 314 or 62.8.
RADIANS_TOL = 2e-4


def _round(value: float, tol: float) -> bool:
    """Whether ``value > 0`` has at most two significant digits (1000, 50, 2.5), to ``tol``."""
    mantissa = 10.0 * value / 10.0 ** np.floor(np.log10(value))  # in [10, 100)
    return abs(mantissa - np.round(mantissa)) <= tol * mantissa


def band_unit_warnings(band_hz: tuple[float, float]) -> list[str]:
    """A band given in rad/s instead of Hz (one line, or none).

    The rule: a limit that is not itself a round number but is 2 pi times one within
    :data:`RADIANS_TOL` (``f_max_hz = 6283.19`` = 2 pi x 1000) was most likely converted to
    rad/s. Round limits (``1000``, ``250``) never warn.

    Parameters
    ----------
    band_hz : (float, float)
        ``(f_min, f_max)`` of the job, in 1/(model time unit).
    """
    suspects = []
    for key, value in zip(("f_min_hz", "f_max_hz"), band_hz, strict=True):
        value = float(value)
        if value > 0 and not _round(value, 1e-9) and _round(value / (2 * np.pi), RADIANS_TOL):
            suspects.append(f"{key} = {value:g} is 2 pi x {value / (2 * np.pi):.4g}")
    if not suspects:
        return []
    return [
        f"band {', '.join(suspects)}: a band in rad/s? [band] is in Hz (cycles per time "
        "unit of the model); divide by 2 pi"
    ]


def convert_body(
    body: ElasticBody, source: UnitSystem | str, target: UnitSystem | str
) -> ElasticBody:
    """The same body in another consistent unit system.

    Displacement dofs scale with the length unit, rotations are unchanged; energies (``q^T K q``)
    with the force x length unit and kinetic energies with mass x length^2 / time^2, so
    ``K' = e S^-1 K S^-1``, ``M' = e tau^2 S^-1 M S^-1``, ``D' = e tau S^-1 D S^-1`` with ``S`` the
    dof scales, ``e`` the energy factor and ``tau`` the time factor. Constraint equations and
    coordinates scale accordingly; eigenfrequencies change by ``1 / tau`` (none between two
    systems in seconds).

    Parameters
    ----------
    body : ElasticBody
    source, target : UnitSystem or str
        Systems (or their names in :data:`SYSTEMS`).
    """
    by_name = {s.name: s for s in SYSTEMS}
    src = by_name[source] if isinstance(source, str) else source
    dst = by_name[target] if isinstance(target, str) else target
    length = src.length_m / dst.length_m  # new length units per old one
    mass = src.mass_kg / dst.mass_kg
    tau = src.time_s / dst.time_s  # new time units per old one
    energy = mass * length**2 / tau**2  # kinetic energy unit: mass length^2 / time^2
    scale = np.where(body.dofs.directions < 3, length, 1.0)
    inverse = sp.diags(1.0 / scale)

    def transform(matrix: sp.spmatrix | None, factor: float) -> sp.csr_matrix | None:
        if matrix is None:
            return None
        return sp.csr_matrix(factor * (inverse @ matrix @ inverse))

    constraints = body.constraints
    if constraints is not None and len(constraints):
        g = sp.diags(scale[constraints.dependent]) @ constraints.matrix @ inverse
        constraints = ConstraintEquations(
            constraints.dependent, g, constraints.offset * scale[constraints.dependent]
        )
    return replace(
        body,
        coordinates=body.coordinates * length,
        mass=transform(body.mass, energy * tau**2),
        stiffness=transform(body.stiffness, energy),
        damping_matrix=transform(body.damping_matrix, energy * tau),
        constraints=constraints,
    )


__all__ = [
    "SYSTEMS",
    "UnitGuess",
    "UnitSystem",
    "band_unit_warnings",
    "convert_body",
    "detect_units",
    "frequency_warnings",
    "implied_numbers",
    "length_unit_name",
    "material_systems",
    "units_of_numbers",
]
