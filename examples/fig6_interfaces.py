"""Paper Fig. 6: the frequency response of the solid rack for the interface variants of node 2.

For each way of coupling the interface node 2 to the surface of the upper hole (paper section
2.2: rigid constraints, a distributing constraint, steel beams, light stiff beams, springs), the
rack is clamped at node 2 (tangent frame) and ``||H(i omega)||_F`` of the three forces and
displacements at node 1 is plotted over 0-1000 Hz.

The response of each 35,000-dof variant is evaluated through a second-order Krylov model of it
(expansion points over the band), whose error against the full model is *checked* at several
frequencies -- full sparse solves -- and printed; a variant whose check fails is reported, not
plotted silently. Usage::

    .venv/bin/python examples/fig6_interfaces.py [--dofs 35000] [--out out/fig6]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from threadpoolctl import threadpool_limits

from pymorembs.analysis.error import relative_error
from pymorembs.analysis.transfer import transfer_function
from pymorembs.body import Damping
from pymorembs.examples import build_example
from pymorembs.preparation import Frame, Port, prepare
from pymorembs.reduction.krylov import krylov_reduction
from pymorembs.reduction.projection import reduced_model

VARIANTS = ("rigid", "distributing", "steel-beams", "light-beams", "springs")
CHECK_HZ = np.array([5.0, 150.0, 400.0, 650.0, 900.0])
#: Largest relative error (eq. 27) of the Krylov model at the check frequencies.
CHECK_LIMIT = 1e-6


def response(dofs: int, variant: str, frequencies: np.ndarray) -> tuple[np.ndarray, dict]:
    """``||H||_F`` at the frequencies, and facts of the computation."""
    body = build_example("rack-solid", dofs=dofs, interface=variant)
    body = body.with_damping(Damping("modal", ratio=0.01))
    ports = [Port.parse(1, "ux uy uz")]
    prepared = prepare(body, Frame("tangent", 2), ports, ports)
    start = time.perf_counter()
    points = np.linspace(0.0, 1000.0, 6)
    model = reduced_model(prepared.system, krylov_reduction(prepared.system, points, moments=4))
    check = relative_error(
        transfer_function(prepared.system, CHECK_HZ), transfer_function(model.system, CHECK_HZ)
    )
    h = transfer_function(model.system, frequencies)
    facts = {
        "n_dof": body.n_dof,
        "order": model.projection.order,
        "check_hz": CHECK_HZ.tolist(),
        "check_rel_error": check.tolist(),
        "seconds": time.perf_counter() - start,
    }
    return np.linalg.norm(h, axis=(1, 2)), facts


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dofs", type=int, default=35_000, help="size of the rack-solid model")
    parser.add_argument("--out", type=Path, default=Path("out/fig6"), help="output folder")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    frequencies = np.linspace(0.0, 1000.0, 1001)
    curves, report, failed = {}, {}, []
    with threadpool_limits(1, "blas"):
        for variant in VARIANTS:
            norm, facts = response(args.dofs, variant, frequencies)
            report[variant] = facts
            worst = max(facts["check_rel_error"])
            print(
                f"{variant:<13} {facts['n_dof']:>7} dofs  Krylov order {facts['order']:>3}  "
                f"check error {worst:.1e}  {facts['seconds']:6.1f} s",
                flush=True,
            )
            if worst > CHECK_LIMIT:
                failed.append(variant)
                continue
            curves[variant] = norm
    fig, ax = plt.subplots(figsize=(8, 4.5), dpi=120)
    for variant, norm in curves.items():
        ax.semilogy(frequencies, norm, label=variant, lw=1.3)
    ax.set_xlabel("frequency f [Hz]")
    ax.set_ylabel(r"$\|H(i\omega)\|_F$ [m/N]")
    ax.set_title(f"rack-solid ({report[VARIANTS[0]]['n_dof']} dofs): interface variants of node 2")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(args.out / "fig6_interfaces.png")
    np.savetxt(
        args.out / "fig6_interfaces.csv",
        np.column_stack([frequencies, *curves.values()]),
        delimiter=",",
        header="frequency_hz," + ",".join(curves),
        comments="",
    )
    (args.out / "fig6_interfaces.json").write_text(json.dumps(report, indent=2) + "\n")
    print(f"written: {args.out}/fig6_interfaces.png, .csv, .json")
    if failed:
        print(f"check failed for {', '.join(failed)}: not plotted", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
