"""The reduced body in the formats multibody codes read (paper section 4).

* :mod:`~pymorembs.export.invariants`: the mass invariants of the reduced body (SID_NOTES §4).
* :mod:`~pymorembs.export.sid`: Standard Input Data (``.SID_FEM``) writer, reader and checks.
* :mod:`~pymorembs.export.exudyn_body`: a body for Exudyn's ``ObjectFFRFreducedOrder``.
"""
