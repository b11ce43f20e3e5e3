"""``pymorembs info`` run in-process, for the tests of readers and checks."""

from __future__ import annotations

import json
from pathlib import Path

from pymorembs.job.cli import main


def info_facts(capsys, *args: str | Path, modes: int = 12) -> dict:
    """The facts of an ``info --json`` that must exit 0."""
    code = main(["info", *map(str, args), "--modes", str(modes), "--json"])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    return json.loads(captured.out)


def refused(capsys, *args: str | Path, modes: int = 12) -> str:
    """The one line of an ``info`` that must exit 2 (without the ``pymorembs: error:`` prefix)."""
    code = main(["info", *map(str, args), "--modes", str(modes)])
    captured = capsys.readouterr()
    assert code == 2, captured.out
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in captured.err, captured.err
    return lines[0].removeprefix("pymorembs: error: ")
