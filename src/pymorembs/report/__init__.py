"""Plots and reports of reduction jobs (matplotlib, one self-contained HTML page).

A public subpackage (``docs/api.md``, "The public surface"): the error curves
(:func:`plot_relative_errors`, paper Fig. 10), the decay of singular values (:func:`plot_decay`,
Fig. 11), time responses (:func:`plot_time_responses`, Fig. 12), the large-motion checks
(:func:`plot_large_motion`), the stress histories at hot spots of both
(:func:`plot_stress_histories`, :func:`plot_large_motion_stresses`) and the job's HTML page
(:func:`write_report`) with its 3D view of the body (:func:`body_scene`,
:func:`reductions_scene`, the WebGL code :func:`viewer_script`).
Importing it imports matplotlib (``Agg`` backend).
"""

from pymorembs.report.html_report import write_report
from pymorembs.report.plots import plot_decay, plot_relative_errors
from pymorembs.report.scene import body_scene, reductions_scene, viewer_script
from pymorembs.report.time_plots import (
    plot_large_motion,
    plot_large_motion_stresses,
    plot_stress_histories,
    plot_time_responses,
)

__all__ = [
    "body_scene",
    "plot_decay",
    "plot_large_motion",
    "plot_large_motion_stresses",
    "plot_relative_errors",
    "plot_stress_histories",
    "plot_time_responses",
    "reductions_scene",
    "viewer_script",
    "write_report",
]
