"""The tests run from any checkout: no test reaches a file by an absolute path (issue #16)."""

from __future__ import annotations

import re
from pathlib import Path

TESTS = Path(__file__).parent
#: A string literal that starts an absolute path on Linux, macOS or Windows.
ABSOLUTE = re.compile(r"""["'](/(work|home|Users|root|mnt|opt|srv|data)/|[A-Za-z]:\\\\)""")


def test_no_test_names_an_absolute_path():
    found = []
    for path in sorted(TESTS.rglob("*.py")):
        if path.name == Path(__file__).name:
            continue  # the examples below
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1):
            if ABSOLUTE.search(line):
                found.append(f"{path.relative_to(TESTS)}:{number}: {line.strip()}")
    assert found == []


def test_the_pattern_finds_what_it_is_for():
    assert ABSOLUTE.search('REFERENCE = Path("/work/shared/reference/sid")')
    assert ABSOLUTE.search("open('C:\\\\models\\\\k.mtx')")
    assert not ABSOLUTE.search('Path(__file__).parent / "data"')
