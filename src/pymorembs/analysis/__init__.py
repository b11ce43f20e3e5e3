"""Judging reduced models: frequency responses, the error of eq. 27, time and large motions.

A public subpackage (``docs/api.md``, "The public surface"): the names below are its interface,
the modules behind them are not.

* frequency responses and errors: :func:`transfer_function`, :func:`frequency_grid`,
  :func:`relative_error`, :func:`error_blocks`, :func:`stress_block`;
* the reference the errors are measured against (:mod:`~pymorembs.analysis.reference`):
  :func:`reference_response`, :class:`ReferenceResponse`;
* the spectrum of a body as read: :func:`model_facts`;
* the (mass-weighted) modal assurance criterion between two bases: :func:`mac`;
* time responses (paper section 5.1): :class:`LoadCase`, :func:`simulate`, the clamped full
  and reduced systems, :func:`compare`; stress histories at hot spots (:class:`StressHistory`,
  :func:`compare_stresses`, :func:`compare_histories`; the run folder's file of them,
  :data:`HISTORY_FILE`: :func:`history_arrays`, :func:`histories_from_arrays`);
* an exported body in Exudyn (:mod:`~pymorembs.analysis.exudyn_model`):
  :func:`build_exudyn_model`, :func:`simulate_exudyn`;
* large motions in Exudyn: :class:`LargeMotionSettings`, :func:`large_motion_checks` and its
  :class:`LargeMotionResult`.
"""

from pymorembs.analysis.error import error_blocks, relative_error, stress_block
from pymorembs.analysis.exudyn_model import build_exudyn_model, simulate_exudyn
from pymorembs.analysis.large_motion import (
    LARGE_MOTION_CASES,
    LargeMotionResult,
    LargeMotionSettings,
    large_motion_checks,
)
from pymorembs.analysis.mac import mac
from pymorembs.analysis.reference import (
    DEFAULT_CHECKS,
    REFERENCE_KINDS,
    ReferenceResponse,
    choose_kind,
    reference_response,
)
from pymorembs.analysis.spectrum import model_facts
from pymorembs.analysis.stress_history import (
    HISTORY_FILE,
    STRESS_COVERS,
    HotSpotStress,
    StressComparison,
    StressHistory,
    compare_histories,
    histories_from_arrays,
    history_arrays,
    hot_spot_entries,
    hot_spot_labels,
    stress_history,
    stress_settings,
)
from pymorembs.analysis.time_domain import (
    LoadCase,
    TimeResponse,
    clamped_full_model,
    clamped_full_system,
    clamped_reduced_system,
    compare,
    compare_stresses,
    full_stress_rows,
    simulate,
)
from pymorembs.analysis.transfer import transfer_function
from pymorembs.frequencies import frequency_grid

__all__ = [
    "DEFAULT_CHECKS",
    "HISTORY_FILE",
    "LARGE_MOTION_CASES",
    "REFERENCE_KINDS",
    "STRESS_COVERS",
    "HotSpotStress",
    "LargeMotionResult",
    "LargeMotionSettings",
    "LoadCase",
    "ReferenceResponse",
    "StressComparison",
    "StressHistory",
    "TimeResponse",
    "build_exudyn_model",
    "choose_kind",
    "clamped_full_model",
    "clamped_full_system",
    "clamped_reduced_system",
    "compare",
    "compare_histories",
    "compare_stresses",
    "error_blocks",
    "frequency_grid",
    "full_stress_rows",
    "histories_from_arrays",
    "history_arrays",
    "hot_spot_entries",
    "hot_spot_labels",
    "large_motion_checks",
    "mac",
    "model_facts",
    "reference_response",
    "relative_error",
    "simulate",
    "simulate_exudyn",
    "stress_block",
    "stress_history",
    "stress_settings",
    "transfer_function",
]
