"""CalculiX peer: ``pymorembs info --modes 20`` against CalculiX's own modal analysis of the same
mesh, side by side in one run, and the read speed of the CalculiX text export.

The part (issue #30, item 2): an L-shaped steel bracket with two pin holes, meshed by gmsh into
quadratic tetrahedra of about ``--dofs`` dofs (``bench/bracket_part.py``, run by a Python with
``gmsh`` and ``numpy``: ``--gmsh-python``, default ``$GMSH_PYTHON`` or ``/tmp/gmshv/bin/python``),
written as two CalculiX decks into ``bench/.cache/calculix-peer-<dofs>/`` and exported once by
``ccx -i bracket`` (``*FREQUENCY, SOLVER=MATRIXSTORAGE``: ``bracket.sti``, ``bracket.mas``,
``bracket.dof``). The cache is kept; delete it to make the part again.

Measured, each in a fresh process, one after the other (pymorembs first), with
``OMP_NUM_THREADS`` = ``--threads`` (default 2) for both programs:

``calculix``
    ``ccx -i bracket_modes`` in a directory of its own: ``*FREQUENCY`` of ``--modes`` (20)
    eigenvalues, free-free, CalculiX's default solver (SPOOLES and ARPACK's shift-invert
    Lanczos). Wall time, peak memory (``ru_maxrss`` of the process), the frequencies it writes
    into ``bracket_modes.dat`` (7 significant digits).
``pymorembs``
    ``pymorembs info bracket.sti --modes 20 --json`` on CalculiX's export, the command as a user
    runs it (the process's whole wall time, interpreter start included), its default linear
    solver (PARDISO where installed). The child wraps the command's own steps to split the wall
    time: start (interpreter, imports), read (``read_body``: the three text files and the
    deck), validation (``validate_body`` and ``prepare``), modes (``model_facts``: rigid-body
    modes decided and the elastic modes with their rounding bounds). ``--modes 20`` asks for
    20 *elastic* modes; CalculiX's 20 include the six rigid-body modes, so pymorembs computes
    six modes more. The first 14 elastic frequencies are compared with CalculiX's modes 7-20
    (relative difference; CalculiX prints 7 digits, so ~1e-7 is agreement).
``read``, ``baseline``
    Read speed of the export: the CalculiX reader (``read_calculix``: ``.sti``, ``.mas``,
    ``.dof`` and the deck, every check) against a plain C-speed parse of the same numbers
    (NumPy's ``loadtxt`` of the ``row column value`` lines of both matrices, of the ``.dof``
    lines and of the deck's ``*NODE`` lines), as ``bench/read_speed.py`` measures the other
    text formats (memory ``warm``: the child touches and frees twice the files' size first).
    Memory: peak above the process's memory before the read against the CSR bytes of K and M.
    The reader runs twice, with Numba's cache in a new empty directory (``NUMBA_CACHE_DIR``):
    *cold*, its compiled kernels compiled within the read, as on the first read after
    installing, then *warm*, loaded from the cache the first run wrote.

Targets: pymorembs / CalculiX wall time <= 1; read time / baseline <= 2; read memory / K+M CSR
<= 2. The section "CalculiX peer (modal analysis)" of ``bench/RESULTS.md`` is replaced.

``--read-only`` measures the read speed alone (no CalculiX run, no ``pymorembs info``; its
section is "CalculiX peer (modal analysis), read only"); ``--no-read`` leaves it out.

Usage (a 280k run takes about 10 minutes and up to 8 GB; run it under the shared lock)::

    flock /work/locks/big .venv/bin/python bench/calculix_peer.py --dofs 283000
    flock /work/locks/big .venv/bin/python bench/calculix_peer.py --dofs 283000 --read-only
    .venv/bin/python bench/calculix_peer.py --quick          # 20,000 dofs, about a minute
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import _common as common
import numpy as np

BENCH = Path(__file__).resolve().parent
PART_SCRIPT = BENCH / "bracket_part.py"
QUICK_DOFS = 20_000
#: CalculiX's modes that are rigid-body modes of the free bracket.
RIGID = 6
SECTION = "CalculiX peer (modal analysis)"


# =========================================================================== the part
def gmsh_python(given: str | None) -> str:
    """The Python that runs ``bracket_part.py`` (one with gmsh and numpy)."""
    for candidate in (given, os.environ.get("GMSH_PYTHON"), "/tmp/gmshv/bin/python"):
        if candidate and Path(candidate).exists():
            return candidate
    return sys.executable


def make_part(dofs: int, work: Path, python: str, threads: int) -> dict:
    """The decks and CalculiX's matrix export in ``work`` (made once, then read from there)."""
    facts_file = work / "export.json"
    if facts_file.exists():
        return json.loads(facts_file.read_text())
    work.mkdir(parents=True, exist_ok=True)
    tick = time.perf_counter()
    subprocess.run([python, str(PART_SCRIPT), "--dofs", str(dofs), "--out", str(work)], check=True)
    mesh_s = time.perf_counter() - tick
    run = run_measured(["ccx", "-i", "bracket"], work, threads)
    if run["returncode"] != 0 or not (work / "bracket.sti").exists():
        raise SystemExit(f"ccx -i bracket failed: {run['tail']}")
    facts = json.loads((work / "mesh.json").read_text())
    facts.update(mesh_s=round(mesh_s, 1), export_s=round(run["seconds"], 1))
    facts_file.write_text(json.dumps(facts, indent=1) + "\n")
    return facts


# =========================================================================== measuring a process
def run_measured(command: list[str], cwd: Path, threads: int) -> dict:
    """Run ``command`` in ``cwd``: wall time, peak memory (``ru_maxrss``), output."""
    env = dict(os.environ, OMP_NUM_THREADS=str(threads))
    out, err = cwd / f".{Path(command[0]).name}.out", cwd / f".{Path(command[0]).name}.err"
    with open(out, "wb") as stdout, open(err, "wb") as stderr:
        tick = time.perf_counter()
        process = subprocess.Popen(command, cwd=cwd, env=env, stdout=stdout, stderr=stderr)
        _, status, usage = os.wait4(process.pid, 0)
        seconds = time.perf_counter() - tick
    text = out.read_text(errors="replace")
    tail = (err.read_text(errors="replace").strip().splitlines() or ["no output"])[-1]
    return {
        "seconds": seconds,
        "peak_mb": usage.ru_maxrss / 1024.0,
        "returncode": os.waitstatus_to_exitcode(status),
        "stdout": text,
        "tail": tail,
    }


def calculix_frequencies(dat: Path) -> np.ndarray:
    """The frequencies (cycles/time) of the eigenvalue output in CalculiX's ``.dat`` file; a
    negative eigenvalue gives ``-sqrt(-lambda) / 2 pi``."""
    text = dat.read_text()
    start = text.index("E I G E N V A L U E   O U T P U T")
    values = []
    for line in text[start:].splitlines()[5:]:
        fields = line.split()
        if len(fields) != 5 or not fields[0].isdigit():
            if values:
                break
            continue
        values.append(float(fields[1]))
    eigenvalues = np.asarray(values)
    return np.sign(eigenvalues) * np.sqrt(np.abs(eigenvalues)) / (2 * np.pi)


def run_calculix(work: Path, modes: int, threads: int) -> dict:
    """CalculiX's ``*FREQUENCY`` of ``modes`` eigenvalues in a fresh directory."""
    run_dir = work / "calculix-run"
    if run_dir.exists():
        shutil.rmtree(run_dir)
    run_dir.mkdir()
    deck = (work / "bracket_modes.inp").read_text()
    deck = re.sub(r"\*FREQUENCY\n\d+\n", f"*FREQUENCY\n{modes}\n", deck)
    (run_dir / "bracket_modes.inp").write_text(deck)
    run = run_measured(["ccx", "-i", "bracket_modes"], run_dir, threads)
    if run["returncode"] != 0:
        return {"failed": f"ccx exit {run['returncode']}: {run['tail']}"}
    return {
        "seconds": run["seconds"],
        "peak_mb": run["peak_mb"],
        "frequencies_hz": calculix_frequencies(run_dir / "bracket_modes.dat").tolist(),
    }


# =========================================================================== pymorembs info
def run_info(sti: Path, modes: int, threads: int) -> dict:
    """``pymorembs info`` (through :func:`info_child`) in a fresh process."""
    run = run_measured(
        [sys.executable, __file__, "--child", "info", str(sti), str(modes)], sti.parent, threads
    )
    lines = [x for x in run["stdout"].splitlines() if x.startswith("RESULT ")]
    if run["returncode"] != 0 or not lines:
        return {"failed": f"exit {run['returncode']}: {run['tail']}"[:200]}
    result = json.loads(lines[-1][len("RESULT ") :])
    result.update(seconds=run["seconds"], peak_mb=run["peak_mb"])
    return result


def process_age_s() -> float:
    """Seconds since this process started (``/proc``: clock ticks, 10 ms)."""
    ticks = int(Path("/proc/self/stat").read_text().rsplit(")", 1)[1].split()[19])
    uptime = float(Path("/proc/uptime").read_text().split()[0])
    return uptime - ticks / os.sysconf("SC_CLK_TCK")


def info_child(sti: str, modes: int) -> None:
    """Run ``pymorembs info sti --modes modes --json`` with its steps timed (module docstring)."""
    from pymorembs.job import cli

    imported = time.perf_counter()
    since_start = process_age_s()
    steps: dict[str, float] = {"read": 0.0, "validation": 0.0, "modes": 0.0}

    def timed(step: str, function):
        def wrapper(*args, **kwargs):
            tick = time.perf_counter()
            try:
                return function(*args, **kwargs)
            finally:
                steps[step] += time.perf_counter() - tick

        return wrapper

    cli.read_body = timed("read", cli.read_body)
    cli.validate_body = timed("validation", cli.validate_body)
    cli.prepare = timed("validation", cli.prepare)
    cli.model_facts = timed("modes", cli.model_facts)
    output = io.StringIO()
    with contextlib.redirect_stdout(output):
        code = cli.main(["info", sti, "--modes", str(modes), "--json"])
    done = time.perf_counter()
    if code != 0:
        raise SystemExit(code)
    facts = json.loads(output.getvalue())
    common.emit(
        {
            "import_s": since_start,
            "command_s": done - imported,
            **{f"{k}_s": v for k, v in steps.items()},
            "rigid_body_modes": facts["rigid_body_modes"],
            "frequencies_hz": facts["eigenfrequencies_hz"],
            "n_dof": facts["n_dof"],
        }
    )


# =========================================================================== read speed
def read_child(role: str, sti: str) -> None:
    """Time and peak memory of the CalculiX reader or of the plain parse (module docstring)."""
    from read_speed import warm_memory

    path = Path(sti)
    files = [path, path.with_suffix(".mas"), path.with_suffix(".dof"), path.with_suffix(".inp")]
    if role == "read":
        from pymorembs.io.calculix import read_calculix

        def call():
            return read_calculix(path)
    else:

        def call():
            kinds = [("row", np.int64), ("column", np.int64), ("value", float)]
            return [
                np.loadtxt(files[0], dtype=kinds),
                np.loadtxt(files[1], dtype=kinds),
                np.loadtxt(files[2]),
                deck_nodes(files[3]),
            ]

    warm_memory(int(2 * sum(f.stat().st_size for f in files)))
    common.reset_peak_memory()
    before = common.rss_mb()
    tick, cpu = time.perf_counter(), time.process_time()
    result = call()
    seconds, cpu = time.perf_counter() - tick, time.process_time() - cpu
    out = {"seconds": seconds, "cpu_s": cpu, "peak_mb": common.peak_memory_mb() - before}
    if role == "read":
        out["matrix_mb"] = (
            sum(a.data.nbytes + a.indices.nbytes + a.indptr.nbytes
                for a in (result.stiffness, result.mass)) / 2**20
        )  # fmt: skip
    common.emit(out)


def deck_nodes(inp: Path) -> np.ndarray:
    """The ``*NODE`` lines of a deck by ``loadtxt`` (the block found by a byte search)."""
    data = inp.read_bytes()
    start = data.index(b"\n", data.index(b"*NODE")) + 1
    stop = data.index(b"\n*", start) + 1
    return np.loadtxt(io.BytesIO(data[start:stop]), delimiter=",")


def files_mb(sti: Path) -> float:
    """Size of the export read (``.sti``, ``.mas``, ``.dof``, ``.inp``), MB."""
    return sum(sti.with_suffix(s).stat().st_size for s in (".sti", ".mas", ".dof", ".inp")) / 2**20


def read_speed(sti: Path) -> list[str] | None:
    """The reader cold and warm and the plain parse, each in a fresh process (module
    docstring): the lines of the section, or None if a run failed."""
    with tempfile.TemporaryDirectory(prefix="numba-cache-") as cache:
        env = {"NUMBA_CACHE_DIR": cache}
        runs = {
            cache_state: common.run_child([__file__, "--child", "read", str(sti), "-"], env=env)
            for cache_state in ("cold", "warm")
        }
    base = common.run_child([__file__, "--child", "baseline", str(sti), "-"])
    if any("failed" in r for r in (*runs.values(), base)):
        print(f"read speed failed: {runs} {base}")
        return None
    rows = []
    for cache_state, read in runs.items():
        time_ratio = read["seconds"] / base["seconds"]
        memory_ratio = read["peak_mb"] / read["matrix_mb"]
        ok = "yes" if time_ratio <= 2 and memory_ratio <= 2 else "**no**"
        rows.append(
            [
                cache_state,
                f"{files_mb(sti):.0f}",
                common.fmt_s(read["seconds"]),
                common.fmt_s(base["seconds"]),
                f"{time_ratio:.2f}",
                f"{read['cpu_s'] / base['cpu_s']:.2f}",
                f"{read['peak_mb']:.0f}",
                f"{read['matrix_mb']:.0f}",
                f"{memory_ratio:.2f}",
                ok,
            ]
        )
    headers = [
        "Numba cache",
        "files [MB]",
        "reader [s]",
        "loadtxt baseline [s]",
        "time ratio",
        "CPU time ratio",
        "reader peak [MB]",
        "K+M CSR [MB]",
        "memory ratio",
        "targets met",
    ]
    table = common.markdown_table(headers, rows)
    print(table)
    return [
        "Read speed of the export (`read_calculix`: `.sti`, `.mas`, `.dof`, the deck, every "
        "check) against NumPy's `loadtxt` of the same numbers, each in a fresh process, memory "
        "warm (as `bench/read_speed.py`); memory ratio = reader peak above its memory before "
        "the read / CSR bytes of K and M. The reader with an empty Numba cache (cold: its "
        "kernels compiled in the read, as on the first read after installing), then with the "
        "cache that run wrote (warm). Targets <= 2.",
        "",
        table,
    ]


# =========================================================================== driver
def compare(pymorembs: dict, calculix: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """CalculiX's elastic frequencies, pymorembs' first as many, their relative differences."""
    ccx = np.asarray(calculix["frequencies_hz"])[RIGID:]
    ours = np.asarray(pymorembs["frequencies_hz"])[pymorembs["rigid_body_modes"] :][: ccx.size]
    return ccx, ours, np.abs(ours - ccx) / ccx


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--dofs", type=int, default=283_000, help="about this many dofs")
    parser.add_argument("--quick", action="store_true", help=f"{QUICK_DOFS} dofs")
    parser.add_argument("--modes", type=int, default=20)
    parser.add_argument("--threads", type=int, default=2, help="OMP_NUM_THREADS of both")
    parser.add_argument("--gmsh-python", help="a Python with gmsh and numpy")
    parser.add_argument("--work", type=Path, help="part cache (default bench/.cache/...)")
    parser.add_argument("--no-read", action="store_true", help="skip the read speed")
    parser.add_argument("--read-only", action="store_true", help="the read speed alone")
    parser.add_argument("--no-results", action="store_true", help="do not write RESULTS.md")
    parser.add_argument("--child", nargs=3, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        role, sti, extra = args.child
        if role == "info":
            info_child(sti, int(extra))
        else:
            read_child(role, sti)
        return
    dofs = QUICK_DOFS if args.quick else args.dofs
    work = args.work or common.CACHE / f"calculix-peer-{dofs}"
    part = make_part(dofs, work, gmsh_python(args.gmsh_python), args.threads)
    sti = work / "bracket.sti"
    print(f"part: {part['dofs']} dofs, {part['elements']} C3D10 ({work})", flush=True)
    if args.read_only:
        ours = calculix = {}
    else:
        ours = run_info(sti, args.modes, args.threads)
        print(f"pymorembs: {ours.get('failed') or json.dumps(ours)}", flush=True)
        calculix = run_calculix(work, args.modes, args.threads)
        print(f"calculix: {calculix.get('failed') or json.dumps(calculix)}", flush=True)
    failed = "failed" in calculix or "failed" in ours
    lines = [
        f"Part: L-shaped steel bracket with two pin holes (`bench/bracket_part.py`), gmsh "
        f"{part['gmsh']}, {part['elements']:,} C3D10, **{part['dofs']:,} dofs**, free-free; "
        f"matrices exported by CalculiX (`*FREQUENCY, SOLVER=MATRIXSTORAGE`, "
        f"{2 * sti.stat().st_size / 2**20:.0f} MB of text). Each program in a fresh process, "
        f"`OMP_NUM_THREADS={args.threads}`.",
        "",
    ]
    if not failed and not args.read_only:
        ccx, mine, difference = compare(ours, calculix)
        ratio = ours["seconds"] / calculix["seconds"]
        rest = ours["seconds"] - ours["import_s"] - ours["read_s"] - ours["validation_s"]
        rest -= ours["modes_s"]
        headers = [
            "program",
            "wall [s]",
            "peak memory [MB]",
            "start [s]",
            "read [s]",
            "validation [s]",
            "modes [s]",
            "other [s]",
        ]
        rows = [
            [
                f"CalculiX {args.modes} modes (`*FREQUENCY`, SPOOLES + ARPACK)",
                common.fmt_s(calculix["seconds"]),
                f"{calculix['peak_mb']:.0f}",
                "",
                "",
                "",
                "",
                "",
            ],
            [
                f"`pymorembs info --modes {args.modes}`",
                common.fmt_s(ours["seconds"]),
                f"{ours['peak_mb']:.0f}",
                common.fmt_s(ours["import_s"]),
                common.fmt_s(ours["read_s"]),
                common.fmt_s(ours["validation_s"]),
                common.fmt_s(ours["modes_s"]),
                common.fmt_s(rest),
            ],
        ]
        verdict = "met" if ratio <= 1 else "**not met**"
        lines += [
            common.markdown_table(headers, rows),
            "",
            f"**Ratio pymorembs / CalculiX: {ratio:.2f}** (target <= 1: {verdict}). "
            f"Frequencies: pymorembs' first {mine.size} elastic modes against CalculiX's modes "
            f"{RIGID + 1}-{RIGID + ccx.size} (7 digits): largest relative difference "
            f"{difference.max():.1e} (mode 7: {ccx[0]:.2f} Hz, mode {RIGID + ccx.size}: "
            f"{ccx[-1]:.2f} Hz). pymorembs found {ours['rigid_body_modes']} rigid-body modes; "
            f"CalculiX's modes 1-6: |f| <= "
            f"{np.abs(calculix['frequencies_hz'][:RIGID]).max():.3g} Hz.",
            "",
        ]
        print("\n".join(lines[-4:]))
        print("CalculiX  " + " ".join(f"{f:.2f}" for f in ccx))
        print("pymorembs " + " ".join(f"{f:.2f}" for f in mine))
    if not args.no_read:
        read_lines = read_speed(sti)
        failed = failed or read_lines is None
        lines += read_lines or ["Read speed: failed"]
    if not args.no_results and not failed:
        name = SECTION + (", quick" if args.quick else "")
        name += ", read only" if args.read_only else ""
        print(
            f"written: {common.update_results(name, chr(10).join(lines), common.machine_facts())}"
        )
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
