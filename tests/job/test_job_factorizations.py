"""A job factorizes each matrix once (linalg.shared_factorizations) and checks its error
reference without complex factorizations; its results are those of the previous way.

The factorizations are counted at the backend; the previous way is the same job with nothing
shared and every check a complex factorization (as the job ran before).
"""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest

import pymorembs.analysis.reference as reference_module
import pymorembs.job.run as run
from pymorembs.job.schema import parse_job
from pymorembs.linalg import factorization, shared_factorizations

DEMO = Path(__file__).resolve().parents[2] / "examples" / "rack-beams-demo.toml"


def job_data() -> dict:
    """The demo job (rack-beams) with 2 % damping, a surrogate reference, Krylov and SOAGA."""
    data = tomllib.loads(DEMO.read_text())
    data["damping"]["ratio"] = 0.02
    data["band"].update(points=200, reference="surrogate")
    data["reduction"] = [
        {"name": "krylov", "method": "krylov", "expansion_points_hz": [0, 500, 1000],
         "moments": [2, 2, 2]},
        {"name": "soaga", "method": "soaga", "tolerance": 1e-6},
    ]  # fmt: skip
    data["export"] = {"outputs": ["sid"]}
    return data


def run_counted(tmp_path, monkeypatch, name):
    """Run the job; the summary and the kinds ('f', 'c') of the factorizations made."""
    kinds = []
    original = factorization.factorize

    def counting(matrix, *args, **kwargs):
        kinds.append(matrix.dtype.kind)
        return original(matrix, *args, **kwargs)

    with monkeypatch.context() as patch:
        patch.setattr(factorization, "factorize", counting)
        summary = run.run_job(parse_job(job_data(), DEMO), tmp_path / name)
    return summary, kinds


@pytest.mark.slow
def test_a_job_makes_fewer_factorizations_and_the_same_errors(tmp_path, monkeypatch):
    monkeypatch.setattr(reference_module, "ITERATIVE_CHECKS", True)
    monkeypatch.setattr(reference_module, "ITERATIVE_MIN_ORDER", 0)  # rack-beams is below it
    now, made = run_counted(tmp_path, monkeypatch, "now")
    with monkeypatch.context() as before_patch:  # the previous way
        before_patch.setattr(run, "shared_factorizations", lambda: shared_factorizations(0.0))
        before_patch.setattr(run, "expansion_candidates", lambda options, band: [])
        before_patch.setattr(reference_module, "ITERATIVE_CHECKS", False)
        before, made_before = run_counted(tmp_path, monkeypatch, "before")
    assert "c" not in made and made_before.count("c") >= 4  # the checks at f > 0
    assert len(made) < len(made_before) - made_before.count("c")  # fewer real ones too
    assert now.reference["checks_from_real_factors"] >= 4
    # the reference model chose its points from the reductions' (Krylov's, SOAGA's candidates)
    offered = {0.0, 500.0, 1000.0, *np.linspace(1.0, 1000.0, 10)}
    assert set(now.reference["expansion_points_hz"]) <= offered
    for a, b in zip(now.reductions, before.reductions, strict=True):
        # both maxima are measured against the full model (settled): equal to the solves'
        # accuracy
        assert a.accuracy.max == pytest.approx(b.accuracy.max, rel=1e-6)
    assert np.isclose(now.reference["accuracy"], before.reference["accuracy"], rtol=0, atol=1e-11)
