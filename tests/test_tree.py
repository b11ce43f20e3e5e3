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


def test_no_module_imports_a_private_name_of_another():
    """Issue #16: modules talk through public names only (``from a import _b`` is refused)."""
    import ast

    source = TESTS.parent / "src" / "pymorembs"
    found = []
    for path in sorted(source.rglob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("pymorembs"):
                for alias in node.names:
                    if alias.name.startswith("_") and not alias.name.startswith("__"):
                        found.append(f"{path.relative_to(source)}: {node.module}.{alias.name}")
    assert found == []


def test_nothing_below_the_job_layer_imports_it():
    import ast

    source = TESTS.parent / "src" / "pymorembs"
    found = []
    for path in sorted(source.rglob("*.py")):
        if path.relative_to(source).parts[0] == "job":
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            names = []
            if isinstance(node, ast.ImportFrom):
                names = [node.module or ""]
            elif isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            found += [f"{path.relative_to(source)}: {n}" for n in names
                      if n == "pymorembs.job" or n.startswith("pymorembs.job.")]  # fmt: skip
    assert found == []
