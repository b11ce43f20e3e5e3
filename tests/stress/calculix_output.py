"""Read what CalculiX printed for the stress checks, with plain Python (no pymorembs).

``.dat``: the ``*EL PRINT`` blocks, one per output and step, lines ``element point v1 .. v6``
(``COORD``: ``element point x y z``). ``.frd``: the nodal blocks ``-4  STRESS`` (written for
``*EL FILE`` ``S``), lines ``-1`` + node (10 columns) + six values of 12 columns in the order
``SXX SYY SZZ SXY SYZ SZX``.
"""

from __future__ import annotations

import gzip
import re
from pathlib import Path

import numpy as np

_DAT_HEADER = re.compile(r"\s*(stresses|strains|global coordinates) \(")
_DAT_KEYS = {"stresses": "S", "strains": "E", "global coordinates": "COORD"}


def read_el_print(path: Path) -> dict[str, list[np.ndarray]]:
    """``{"S": [...], "E": [...], "COORD": [...]}``: per step an array (lines, 2 + values),
    columns element, point, then the values as printed."""
    blocks: dict[str, list[list[list[float]]]] = {key: [] for key in _DAT_KEYS.values()}
    current = None
    for line in path.read_text().splitlines():
        found = _DAT_HEADER.match(line)
        if found:
            current = []
            blocks[_DAT_KEYS[found.group(1)]].append(current)
        elif current is not None and line.split():
            current.append([float(v) for v in line.split()])
    return {key: [np.array(b) for b in steps] for key, steps in blocks.items()}


def read_frd_stresses(path: Path) -> list[dict[int, np.ndarray]]:
    """Per step: node -> the six nodal stresses, reordered to ``xx yy zz xy xz yz``."""
    steps: list[dict[int, np.ndarray]] = []
    current = None
    with gzip.open(path, "rt") as f:
        for line in f:
            if line.startswith(" -4"):
                current = {} if line.split()[1] == "STRESS" else None
                if current is not None:
                    steps.append(current)
            elif line.startswith(" -3"):
                current = None
            elif current is not None and line.startswith(" -1"):
                values = [float(line[13 + 12 * k : 25 + 12 * k]) for k in range(6)]
                current[int(line[3:13])] = np.array(values)[[0, 1, 2, 3, 5, 4]]
    return steps
