"""The documentation works: its links resolve, its Python examples run, so do ``examples/*.py``.

* Every relative link and image of ``README.md`` and ``docs/*.md`` names a file of the
  repository, and every ``#anchor`` a heading of the linked page (GitHub's anchor rules).
* The ``python`` code blocks of each page run in order in one namespace (a block may use the
  names of the blocks above it), in an empty temporary folder. A block preceded by the line
  ``<!-- no-test: reason -->`` is skipped; the reason must be given. A page with the line
  ``<!-- docs-test: slow (reason) -->`` runs in the slow set.
* Every ``examples/*.py`` runs as a script; the long ones are in the slow set.
"""

from __future__ import annotations

import json
import re
import runpy
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]

FENCE = re.compile(r"^(```|~~~)")
LINK = re.compile(r"!?\[(?:[^\]\\]|\\.)*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")
INLINE_CODE = re.compile(r"`[^`]*`")
NO_TEST = re.compile(r"^<!--\s*no-test:\s*(\S.*?)\s*-->$")
SLOW_PAGE = re.compile(r"^<!--\s*docs-test:\s*slow\b.*-->$", re.M)


def _rel(page: Path) -> str:
    return page.relative_to(ROOT).as_posix()


def prose_lines(text: str) -> list[tuple[int, str]]:
    """(line number, line) of the lines outside fenced code blocks."""
    out, fenced = [], False
    for number, line in enumerate(text.splitlines(), 1):
        if FENCE.match(line.lstrip()):
            fenced = not fenced
        elif not fenced:
            out.append((number, line))
    return out


def github_anchor(heading: str) -> str:
    """The anchor GitHub gives a heading: lower case, punctuation dropped, spaces to hyphens."""
    text = re.sub(r"<[^>]+>", "", heading.strip()).lower()
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


def anchors(page: Path) -> set[str]:
    """The anchors of every heading of ``page``; repeated headings get ``-1``, ``-2``, ..."""
    seen: dict[str, int] = {}
    found = set()
    for _, line in prose_lines(page.read_text(encoding="utf-8")):
        match = re.match(r"^#{1,6}\s+(.*?)\s*#*\s*$", line)
        if not match:
            continue
        base = github_anchor(match.group(1))
        count = seen.get(base, 0)
        seen[base] = count + 1
        found.add(base if count == 0 else f"{base}-{count}")
    return found


def links(page: Path) -> list[tuple[int, str]]:
    """(line number, target) of every link and image outside code."""
    out = []
    for number, line in prose_lines(page.read_text(encoding="utf-8")):
        for match in LINK.finditer(INLINE_CODE.sub("", line)):
            out.append((number, match.group(1)))
    return out


def test_anchor_rules():
    # the anchors GitHub shows for headings of the kind these pages use
    assert github_anchor("Reading FE models") == "reading-fe-models"
    assert github_anchor("Paper Figs. 9–11: the methods compared") == (
        "paper-figs-911-the-methods-compared"
    )
    assert github_anchor("The built-in model `rack-beams`") == "the-built-in-model-rack-beams"
    assert github_anchor("SID (`.SID_FEM`)") == "sid-sid_fem"


def test_link_checker_finds_broken_links(tmp_path):
    page = tmp_path / "page.md"
    page.write_text(
        "# Title\n\n## Two words\n\n[a](#two-words) [b](#missing) [c](nowhere.md)\n"
        "```\n[not a link](#in-code)\n```\n`[inline](#code)`\n",
        encoding="utf-8",
    )
    assert anchors(page) == {"title", "two-words"}
    assert [target for _, target in links(page)] == ["#two-words", "#missing", "nowhere.md"]


@pytest.mark.parametrize("page", PAGES, ids=_rel)
def test_links_resolve(page):
    problems = []
    for number, target in links(page):
        if re.match(r"^[a-z][a-z0-9+.-]*:", target):  # http:, https:, mailto:
            continue
        path_part, _, anchor = target.partition("#")
        linked = (page.parent / path_part).resolve() if path_part else page
        if not linked.exists():
            problems.append(f"{_rel(page)}:{number}: {target}: no such file")
        elif ROOT not in linked.parents and linked != ROOT:
            problems.append(f"{_rel(page)}:{number}: {target}: outside the repository")
        elif anchor and (linked.suffix != ".md" or anchor not in anchors(linked)):
            problems.append(f"{_rel(page)}:{number}: {target}: no heading with this anchor")
    assert problems == []


def python_blocks(page: Path) -> list[tuple[int, str]]:
    """(first line, code) of the page's ``python`` blocks that are not marked ``no-test``."""
    lines = page.read_text(encoding="utf-8").splitlines()
    blocks, index = [], 0
    while index < len(lines):
        line = lines[index]
        if re.match(r"^```\s*python\s*$", line):
            previous = next((lines[j] for j in range(index - 1, -1, -1) if lines[j].strip()), "")
            end = next(j for j in range(index + 1, len(lines)) if lines[j].startswith("```"))
            if not NO_TEST.match(previous.strip()):
                assert not previous.strip().startswith("<!-- no-test"), (
                    f"{_rel(page)}:{index}: a no-test mark needs its reason"
                )
                blocks.append((index + 2, "\n".join(lines[index + 1 : end]) + "\n"))
            index = end
        index += 1
    return blocks


PAGES_WITH_CODE = [page for page in PAGES if python_blocks(page)]


def test_block_extraction(tmp_path):
    page = tmp_path / "page.md"
    page.write_text(
        "```python\na = 1\n```\n\n<!-- no-test: needs a licence -->\n```python\nraise SystemExit\n"
        "```\n```toml\nb = 2\n```\n```python\nassert a == 1\n```\n",
        encoding="utf-8",
    )
    assert python_blocks(page) == [(2, "a = 1\n"), (13, "assert a == 1\n")]
    assert not SLOW_PAGE.search(page.read_text(encoding="utf-8"))
    assert SLOW_PAGE.search("text\n<!-- docs-test: slow (Exudyn run) -->\n")


def test_readme_is_a_front_door():
    """Issue #16: the README stays short; the reference material lives in docs/."""
    assert (ROOT / "README.md").stat().st_size <= 12 * 1024


def test_readme_has_code():
    assert ROOT / "README.md" in PAGES_WITH_CODE


@pytest.mark.parametrize(
    "page",
    [
        pytest.param(
            page,
            id=_rel(page),
            marks=[pytest.mark.slow] if SLOW_PAGE.search(page.read_text(encoding="utf-8")) else [],
        )
        for page in PAGES_WITH_CODE
    ],
)
def test_python_blocks_run(page, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    namespace: dict = {"__name__": "__docs__"}
    for first_line, code in python_blocks(page):
        # line numbers of tracebacks are those of the markdown file
        compiled = compile("\n" * (first_line - 1) + code, str(page), "exec")
        exec(compiled, namespace)


#: examples/*.py -> (command-line arguments, slow); every script must be listed here
EXAMPLE_SCRIPTS = {
    "fig6_interfaces.py": (["--dofs", "10000", "--out", "{out}"], True),
}


def test_every_example_script_is_run():
    assert sorted(p.name for p in (ROOT / "examples").glob("*.py")) == sorted(EXAMPLE_SCRIPTS)


@pytest.mark.parametrize(
    "name",
    [
        pytest.param(name, marks=[pytest.mark.slow] if slow else [])
        for name, (_, slow) in sorted(EXAMPLE_SCRIPTS.items())
    ],
)
def test_example_script_runs(name, tmp_path, monkeypatch):
    arguments, _ = EXAMPLE_SCRIPTS[name]
    out = tmp_path / "out"
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(sys, "argv", [name, *(a.format(out=out) for a in arguments)])
    with pytest.raises(SystemExit) as done:
        runpy.run_path(str(ROOT / "examples" / name), run_name="__main__")
    assert done.value.code in (0, None)
    assert out.exists() and any(out.iterdir())
    if name == "fig6_interfaces.py":
        # each variant's Krylov curve was checked against the full model at five frequencies
        facts = json.loads((out / "fig6_interfaces.json").read_text())
        assert len(facts) == 5
        assert all(max(f["check_rel_error"]) <= 1e-6 for f in facts.values())


def readme_walkthrough_job() -> str:
    """The job file of the README's walkthrough (the ``toml`` block after "Write a job")."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    after = text[text.index("Write a job") :]
    start = after.index("```toml\n") + len("```toml\n")
    return after[start : after.index("\n```", start)]


@pytest.mark.slow
def test_readme_walkthrough_on_the_ansys_example(tmp_path, capsys):
    """The walkthrough's job runs on the genuine Ansys export it names and writes a valid SID."""
    from pymorembs.export.sid import check_sid, read_sid
    from pymorembs.job.cli import main

    data = ROOT / "tests" / "data" / "pymapdl_reader_hexbeam"
    # step 2, the README's info line for Ansys: the frequencies Ansys' documentation publishes
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert "pymorembs info Jobname.full --nodes Jobname.cdb" in readme
    assert main(["info", str(data / "file.full"), "--nodes", str(data / "HexBeam.cdb")]) == 0
    printed = capsys.readouterr().out
    listed = [float(m) for m in re.findall(r"^\s+\d+\s+(\d+\.\d+)", printed, re.M)]
    published = [1283.200, 1283.200, 5781.975, 6919.399]  # ansys-mapdl-reader's documentation
    assert listed[:4] == pytest.approx(published, rel=1e-6)

    job = readme_walkthrough_job()
    assert 'file = "Jobname.full"' in job and 'nodes = "Jobname.cdb"' in job
    job = job.replace("Jobname.full", (data / "file.full").as_posix())
    job = job.replace("Jobname.cdb", (data / "HexBeam.cdb").as_posix())
    (tmp_path / "body.toml").write_text(job, encoding="utf-8")
    assert main(["reduce", str(tmp_path / "body.toml"), "--out", str(tmp_path / "out")]) == 0
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    (reduction,) = summary["reductions"]
    # the SOAGA tolerance of the job, checked against the full model's response
    assert summary["reference"]["kind"] == "full"  # 963 dofs: every frequency solved in full
    assert reduction["max_rel_error"] <= 1e-6
    assert reduction["inertia_loads"]["max_rel_error"] <= 1e-6
    sid = tmp_path / "out" / "soaga" / "soaga.SID_FEM"
    assert check_sid(read_sid(sid)) == []
    assert "soaga" in capsys.readouterr().out
