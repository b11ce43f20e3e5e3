"""Property-based tests of the job-file parser (issue #7).

Random text and mutations of the example jobs must give either a job or a :class:`UserError`
whose message is one line naming the job file -- never another exception. The mutations are
those a user makes: a line lost, doubled or moved, a value of the wrong kind or size, a key
misspelled, a table header broken, the file cut off.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pymorembs.errors import UserError
from pymorembs.job.schema import Job, load_job

EXAMPLES = sorted((Path(__file__).resolve().parents[2] / "examples").glob("*.toml"))
SEEDS = [path.read_text(encoding="utf-8") for path in EXAMPLES]

#: Values a mutation may put on the right of ``=`` (TOML syntax, some of it invalid on purpose).
VALUES = [
    "0", "-1", "1e400", "-1e400", "nan", "inf", "-inf", "1e-320", "9" * 40,
    "9223372036854775808", '"x"', '""', '"../../etc"', "true", "[]", "[1, 2", "[[1], [2]]",
    '["ux", 3]', "{}", "{ a = 1 }", "1979-05-27", '"1:ux"', "[0, 500, 1000]", "3.5", "=",
]  # fmt: skip
KEYS = ["order", "node", "directions", "f_max_hz", "method", "name", "points", "kind", "file"]

#: Examples per property; the long fuzzing run sets ``PYMOREMBS_FUZZ_EXAMPLES`` (fuzz/README.md).
EXAMPLES_PER_PROPERTY = int(os.environ.get("PYMOREMBS_FUZZ_EXAMPLES", "150"))

FAST = settings(
    max_examples=EXAMPLES_PER_PROPERTY,
    deadline=None,
    derandomize=True,
    database=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)


def _check(path: Path) -> None:
    """The property: a Job, or a one-line UserError that names the file."""
    try:
        job = load_job(path)
    except UserError as exc:
        message = str(exc)
        assert "\n" not in message.strip(), message
        assert str(path) in message or path.name in message, message
        return
    assert isinstance(job, Job)
    low, high = job.band_hz
    assert math.isfinite(low) and math.isfinite(high) and 0.0 <= low < high


@st.composite
def mutated(draw: st.DrawFn) -> str:
    """An example job with one to four user-like mutations."""
    lines = draw(st.sampled_from(SEEDS)).splitlines()
    for _ in range(draw(st.integers(1, 4))):
        if not lines:
            break
        k = draw(st.integers(0, len(lines) - 1))
        kind = draw(st.integers(0, 6))
        if kind == 0:
            del lines[k]
        elif kind == 1:
            lines.insert(k, lines[k])
        elif kind == 2:
            j = draw(st.integers(0, len(lines) - 1))
            lines[k], lines[j] = lines[j], lines[k]
        elif kind == 3 and "=" in lines[k]:
            key = lines[k].split("=", 1)[0]
            lines[k] = f"{key}= {draw(st.sampled_from(VALUES))}"
        elif kind == 4:
            lines.insert(k, f"{draw(st.sampled_from(KEYS))} = {draw(st.sampled_from(VALUES))}")
        elif kind == 5 and "=" in lines[k]:
            key, value = lines[k].split("=", 1)
            cut = draw(st.integers(0, max(0, len(key.strip()) - 1)))
            lines[k] = key.strip()[:cut] + key.strip()[cut + 1 :] + " =" + value  # a typo
        else:
            text = "\n".join(lines)
            return text[: draw(st.integers(0, len(text)))]  # cut off
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("seed", EXAMPLES, ids=[p.stem for p in EXAMPLES])
def test_the_example_jobs_parse(seed: Path) -> None:
    assert isinstance(load_job(seed), Job)


@FAST
@given(text=mutated())
def test_mutated_jobs_parse_or_fail_in_one_line(tmp_path_factory, text: str) -> None:
    path = tmp_path_factory.mktemp("job") / "job.toml"
    path.write_text(text, encoding="utf-8")
    _check(path)


@FAST
@given(data=st.one_of(st.binary(max_size=400), st.text(max_size=400).map(str.encode)))
def test_random_bytes_parse_or_fail_in_one_line(tmp_path_factory, data: bytes) -> None:
    path = tmp_path_factory.mktemp("job") / "job.toml"
    path.write_bytes(data)
    _check(path)
