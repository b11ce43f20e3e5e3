"""Issue #27 item 4: interrupts and the disk.

SIGINT and SIGTERM end a run with exit 130 / 143 and one line, no traceback, the temporary
folder ``.<name>.*`` next to the output removed and the worker processes ended. A full,
over-quota or read-only output device ends it with exit 2 and one line naming the folder, no
traceback, no half-written output. The signals go to the real command line in a child process;
the full disk is a real 2 MiB tmpfs where ``mount`` is permitted, and an injected ``ENOSPC``
everywhere.
"""

from __future__ import annotations

import builtins
import errno
import io
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from conftest import spring_lattice
from lattice_jobs import SOAGA
from lattice_jobs import lattice_job as job_text
from processes import live_children, running
from pymorembs.errors import UserError
from pymorembs.io.native import write_body_h5
from pymorembs.job.cli import main
from pymorembs.job.run import output_device_error, run_job
from pymorembs.job.schema import load_job

ROOT = Path(__file__).resolve().parents[2]
needs_proc = pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs /proc")


@pytest.fixture
def lattice_job(tmp_path):
    write_body_h5(spring_lattice(), tmp_path / "model.h5")
    path = tmp_path / "job.toml"
    path.write_text(job_text(SOAGA, points=200))
    return path


def staging_left(folder: Path, name: str = "out") -> list[str]:
    return [p.name for p in folder.iterdir() if p.name.startswith(f".{name}.")]


def command(*argv: str) -> subprocess.Popen:
    """``pymorembs`` of this checkout in a child process (its stdout and stderr piped), with
    SIGINT at its default whatever this process inherited (a shell script's background job
    starts with SIGINT ignored, and so would the child: the SIGINT tests failed there)."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(
        p for p in (str(ROOT / "src"), str(ROOT / "tests"), env.get("PYTHONPATH", "")) if p
    )
    return subprocess.Popen(
        [sys.executable, "-m", "pymorembs.job.cli", *argv],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )


def signal_at(process: subprocess.Popen, line_starts: str, sig: int) -> tuple[str, list[int]]:
    """Send ``sig`` once the child printed a stage line starting with ``line_starts`` (after
    its time stamp); the lines it printed and its children then."""
    lines = []
    for line in process.stdout:
        lines.append(line)
        if line.split("] ", 1)[-1].startswith(line_starts):
            time.sleep(0.3)  # into the stage
            workers = live_children(process.pid)
            process.send_signal(sig)
            return "".join(lines), workers
    raise AssertionError(f"the run ended before '{line_starts}': {''.join(lines)}")


@pytest.mark.slow
@needs_proc
def test_ctrl_c_during_the_sweep_of_two_workers(lattice_job, tmp_path):
    """SIGINT while two forked workers solve the frequency response: exit 130, one line, no
    traceback, the workers gone at once (they do not finish their share), no temporary
    folder."""
    lattice_job.write_text(job_text(SOAGA, points=200000))  # a sweep of minutes
    out = tmp_path / "out"
    run = command("reduce", str(lattice_job), "--out", str(out), "--workers", "2")
    try:
        _, workers = signal_at(run, "frequency response", signal.SIGINT)
        assert len(workers) == 2
        _, err = run.communicate(timeout=20)
    finally:
        if run.poll() is None:
            run.kill()
    assert run.returncode == 130
    assert err == "pymorembs: interrupted\n"
    assert not any(running(pid) for pid in workers)
    assert not out.exists() and staging_left(tmp_path) == []


@pytest.mark.slow
@needs_proc
@pytest.mark.parametrize(("sig", "code", "line"), [
    (signal.SIGTERM, 143, "pymorembs: terminated\n"),
    (signal.SIGINT, 130, "pymorembs: interrupted\n"),
])  # fmt: skip
def test_a_signal_during_a_reduction(sig, code, line, tmp_path):
    """SIGTERM (or SIGINT) during a reduction of the rack (its 800 lowest modes, about 7 s on
    an AVX-512 host where 300 took 0.7 s and a signal 0.3 s into the stage once came after the
    run): exit 143 (130), one line; an earlier result in the output folder stays as it was."""
    job = tmp_path / "rack.toml"
    job.write_text(
        '[model]\nexample = "rack-beams"\n[frame]\ntype = "tangent"\nnode = 2\n'
        '[[inputs]]\nnode = 1\ndirections = "ux uy uz"\n[band]\nf_max_hz = 1000\npoints = 200\n'
        '[[reduction]]\nname = "modal"\nmethod = "modal"\norder = 800\nexport_inaccurate = true\n'
    )
    out = tmp_path / "out"
    out.mkdir()
    (out / "summary.json").write_text('{"earlier": true}\n')
    run = command("reduce", str(job), "--out", str(out))
    try:
        printed, _ = signal_at(run, "reduction 'modal'", sig)
        _, err = run.communicate(timeout=60)
    finally:
        if run.poll() is None:
            run.kill()
    assert "frequency response" in printed
    assert (run.returncode, err) == (code, line)
    assert json.loads((out / "summary.json").read_text()) == {"earlier": True}
    assert sorted(p.name for p in out.iterdir()) == ["summary.json"]
    assert staging_left(tmp_path) == []


def test_an_interrupt_in_run_job_leaves_no_temporary_folder(lattice_job, tmp_path, monkeypatch):
    """The API: a KeyboardInterrupt in the middle of run_job (here in the frequency response)
    propagates; the temporary folder next to the output is gone, no output folder appears."""
    from pymorembs.job import run as job_run

    def interrupted(*args, **kwargs):
        assert staging_left(tmp_path), "the temporary folder exists while the job runs"
        raise KeyboardInterrupt

    monkeypatch.setattr(job_run, "reference_response", interrupted)
    with pytest.raises(KeyboardInterrupt):
        run_job(load_job(lattice_job), tmp_path / "out")
    assert staging_left(tmp_path) == [] and not (tmp_path / "out").exists()


@pytest.fixture
def full_device(monkeypatch):
    """Writing any file into an output folder ``.out.*``/``out`` fails with ENOSPC, as on a
    full device (opening for writing is where Python's writers meet it first)."""
    real_open = builtins.open

    def failing_open(file, mode="r", *args, **kwargs):
        name = os.fsdecode(file) if isinstance(file, str | bytes | os.PathLike) else ""
        parts = Path(name).parts
        ours = any(p == "out" or p.startswith(".out.") for p in parts)
        if ours and any(c in mode for c in "wax+"):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), name)
        return real_open(file, mode, *args, **kwargs)

    monkeypatch.setattr(builtins, "open", failing_open)
    monkeypatch.setattr(io, "open", failing_open)


def test_a_full_device_is_one_line_and_writes_nothing(lattice_job, tmp_path, capsys, request):
    """ENOSPC while the results are written: exit 2, one line naming the output folder, the
    earlier result untouched, no temporary folder."""
    out = tmp_path / "out"
    (out / "soaga").mkdir(parents=True)  # an earlier result
    (out / "summary.json").write_text('{"earlier": true}\n')
    (out / "soaga" / "reduced.npz").write_bytes(b"earlier body")
    before = {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file()}
    request.getfixturevalue("full_device")
    code = main(["reduce", str(lattice_job), "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2
    assert err == (
        f"pymorembs: error: no space left on the device of {out}; nothing of this run was "
        "written (free some space, or write elsewhere with --out)\n"
    )
    after = {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file()}
    assert after == before and staging_left(tmp_path) == []


def test_which_errors_are_the_output_devices(tmp_path):
    out = tmp_path / "out"
    staging = tmp_path / ".out.abc123" / "krylov" / "K.mtx"
    full = OSError(errno.ENOSPC, "No space left on device")  # a write: no file name
    assert "no space left on the device of" in str(output_device_error(full, out))
    quota = OSError(errno.EDQUOT, "Disk quota exceeded", str(staging))
    assert str(output_device_error(quota, out)).startswith(
        f"the disk quota is exceeded on the device of {out};"
    )
    # a reader's one-line error raised while handling the OSError of its temporary file
    try:
        try:
            raise OSError(errno.EROFS, "Read-only file system", str(staging))
        except OSError:
            raise UserError(f"{staging}: cannot write: Read-only file system") from None
    except UserError as wrapped:
        message = str(output_device_error(wrapped, out))
    assert message == f"{out} lies on a read-only file system; nothing of this run was written " \
        "(write elsewhere with --out)"  # fmt: skip
    # no permission to read an input is not the output's problem; on the output it is
    model = OSError(errno.EACCES, "Permission denied", str(tmp_path / "model.h5"))
    assert output_device_error(model, out) is None
    denied = OSError(errno.EACCES, "Permission denied", str(out / "summary.json"))
    assert str(output_device_error(denied, out)).startswith(f"no permission to write into {out}")
    assert output_device_error(OSError(errno.ENOENT, "No such file"), out) is None
    assert output_device_error(ValueError("x"), out) is None


def tmpfs(folder: Path, size: str = "2M") -> bool:
    """Mount a tmpfs of ``size`` at ``folder``; False where that is not permitted."""
    folder.mkdir()
    try:
        done = subprocess.run(
            ["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(folder)],
            capture_output=True,
            timeout=20,
        )
    except (OSError, subprocess.TimeoutExpired):
        return False
    return done.returncode == 0


@pytest.mark.slow
def test_a_real_full_tmpfs(tmp_path):
    """The issue's case: a 2 MiB tmpfs as --out of the demo job (its bodies need more): exit 2,
    one line naming the folder, nothing left on the device."""
    device = tmp_path / "small"
    if not tmpfs(device):
        pytest.skip("mounting a tmpfs is not permitted here")
    try:
        run = command(
            "reduce", str(ROOT / "examples" / "rack-beams-demo.toml"), "--out",
            str(device / "body"), "--quiet",
        )  # fmt: skip
        _, err = run.communicate(timeout=600)
        assert run.returncode == 2
        error = [line for line in err.splitlines() if not line.startswith("pymorembs: note: ")]
        assert error == [
            f"pymorembs: error: no space left on the device of {device / 'body'}; nothing of this "
            "run was written (free some space, or write elsewhere with --out)"
        ]
        assert list(device.iterdir()) == []
    finally:
        subprocess.run(["umount", str(device)], capture_output=True, timeout=20)
