"""The summary of a job as a typed value: read back from its JSON, it writes the same JSON."""

from __future__ import annotations

import json

from pymorembs.job.summary import JobSummary


def entry(name: str, met: bool, exported: bool) -> dict:
    return {
        "name": name, "method": "modal", "order": 4, "max_rel_error": 0.5,
        "static_rel_error": None, "error_estimate": None, "error_bound": None,
        "reference_resolved": True, "error_covers": "ports: the port outputs to the port inputs",
        "time_s": 0.1, "parameters": {}, "eigenfrequencies_hz": [1.0, 2.0],
        "highest_frequency_hz": 2.0, "explicit_step_s": 0.01, "files": [f"{name}/error.csv"],
        "inertia_loads": {"max_rel_error": 0.2, "static_rel_error": 0.1, "covers": "loads"},
        "accuracy": {"met": met, "limit": 0.01, "limit_from": "default", "max": 0.5,
                     "ports": 0.5, "inertia_loads": 0.2, "export_inaccurate": exported and not met,
                     "exported": exported},
        "time_domain": {"step": {"name": name, "max_error": 0.1}},
    }  # fmt: skip


SUMMARY = {
    "pymorembs_version": "0", "job": "job.toml", "model": {"name": "m", "inertia_loads": None},
    "units": {}, "validation": {}, "band_hz": [0.0, 100.0], "n_frequencies": 401,
    "reference": {"kind": "full"},
    "reductions": [entry("a", True, True), entry("b", False, True), entry("c", False, False)],
    "warnings": ["w"], "notes": [], "timings_s": {"total_s": 1.0},
    "accuracy": {"met": False, "not_met": ["b", "c"], "not_exported": ["c"]},
    "files": ["summary.json"], "provenance": {}, "time_domain": {"cases": []}, "title": "t",
}  # fmt: skip


def test_a_summary_read_back_writes_the_same_json_in_the_same_order():
    summary = JobSummary.from_json(json.loads(json.dumps(SUMMARY)))
    assert json.dumps(summary.to_json()) == json.dumps(SUMMARY)
    assert summary.reductions[2].accuracy.exported is False
    assert summary.reductions[0].inertia_loads.max_rel_error == 0.2
    assert summary.accuracy == SUMMARY["accuracy"]


def test_a_summary_without_title_and_checks_writes_neither():
    data = {k: v for k, v in SUMMARY.items() if k not in ("title", "time_domain")}
    data["reductions"] = [
        {k: v for k, v in r.items() if k not in ("time_domain", "inertia_loads")}
        for r in SUMMARY["reductions"]
    ]
    assert JobSummary.from_json(data).to_json() == data
