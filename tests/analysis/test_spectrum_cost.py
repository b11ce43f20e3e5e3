"""What the eigen-analysis of ``pymorembs info`` costs on a free body (issue #30, item 2): one
factorization of ``K - sigma M`` shared by the rigid-body probe and the elastic modes, and a
probe of the zero-energy modes and the next one only -- with the frequencies of a dense
solution written here with SciPy's ``eigh``."""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla

import pymorembs.analysis.spectrum as spectrum_module
from conftest import space_truss
from pymorembs.analysis.spectrum import PROBE_EXTRA, RIGID_MAX, model_spectrum
from pymorembs.linalg.factorization import Factorization
from pymorembs.preparation import Frame, prepare


def test_free_body_spectrum_factorizes_once_and_probes_few_modes(monkeypatch):
    body = space_truss(8, 6, 5)  # 720 dofs: above the dense limit, six rigid-body modes
    factorized, asked = [], []
    original_init = Factorization.__init__

    def counting_init(self, *args, **kwargs):
        factorized.append(kwargs.get("label"))
        original_init(self, *args, **kwargs)

    original_eigenmodes = spectrum_module.eigenmodes

    def recording_eigenmodes(system, count, *args, **kwargs):
        asked.append(count)
        return original_eigenmodes(system, count, *args, **kwargs)

    monkeypatch.setattr(Factorization, "__init__", counting_init)
    monkeypatch.setattr(spectrum_module, "eigenmodes", recording_eigenmodes)
    prepared = prepare(body, Frame("none"), allow_rigid_body_modes=True)
    spectrum = model_spectrum(body, prepared, 12)

    assert factorized == ["K - sigma M"]  # one factorization for the probe and the modes
    assert asked == [PROBE_EXTRA, 12]  # the probe: the zero-energy modes and the next two
    assert PROBE_EXTRA == RIGID_MAX + 2
    assert spectrum.rigid.count == 6 and "the spectrum agrees" in spectrum.rigid.explanation
    values = sla.eigh(body.stiffness.toarray(), body.mass.toarray(), eigvals_only=True)
    dense_hz = np.sqrt(values[6:18]) / (2 * np.pi)
    assert np.allclose(spectrum.elastic_hz, dense_hz, rtol=1e-9, atol=0)
