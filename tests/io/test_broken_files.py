"""A corpus of broken input files, each a realistic user mistake, through ``pymorembs info``.

Every case must end with the exact exit code (2: a mistake in the input, 3: a numerical failure
of valid-looking input), exactly one line on stderr that names the file and matches the expected
pattern, nothing on stdout and no traceback. The files are in ``tests/broken/files``; the
commands run in that directory so that the messages name the files as given.
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

from pymorembs.job.cli import main

FILES = Path(__file__).parents[1] / "broken" / "files"

# (arguments after "info", exit code, pattern of the message after "pymorembs: error: ")
CASES: list[tuple[str, int, str]] = [
    # wrong format, wrong extension, wrong encoding
    ("empty.mtx", 2, r"^empty\.mtx: cannot tell the file format \(the file is empty\)"),
    (
        "garbage.pch",
        2,
        r"^garbage\.pch: cannot tell the file format \(the name suggests nastran-dmig, but the "
        r"content does not match\); give --format",
    ),
    ("utf16_K.mtx", 2, r"^utf16_K\.mtx: the file is UTF-16 encoded; save it as UTF-8 or ASCII"),
    (
        "--format matrix-market --stiffness utf16_K.mtx --mass M.mtx",
        2,
        r"^utf16_K\.mtx: not a text file \(expected a Matrix Market file\); it is UTF-16 encoded",
    ),
    (
        "good_STIF1.mtx",
        2,
        r"^good_STIF1\.mtx: the content looks like abaqus, whose matrices come as separate files; "
        r"give them as stiffness and mass",
    ),
    ("model.inp", 2, r"^model\.inp: cannot tell the file format \(it looks like an Abaqus input"),
    (
        "model.full",
        2,
        r"^model\.full: format matrix-market reads a directory \(file\) or the files stiffness "
        r"and mass",
    ),
    (
        "model.rst",
        2,
        r"^model\.rst: an Ansys result file \(\.rst\), not the \.full file of a modal analysis",
    ),
    ("cut.full", 2, r"^cut\.full: file is truncated or damaged \(cannot read the \.full header\)"),
    # Matrix Market + CSV tables
    ("--stiffness truncated_K.mtx --mass M.mtx", 2, r"^truncated_K\.mtx:7: 2 values, expected 3"),
    # past 64 KiB of entries the fast path reads first; it must decline these, not misread them
    (
        "--stiffness double_point_K.mtx --mass M.mtx",
        2,
        r"^double_point_K\.mtx:3002: value '1\.0\.5' is not a number$",
    ),
    (
        "--stiffness fraction_index_K.mtx --mass M.mtx",
        2,
        r"^fraction_index_K\.mtx:4002: column '4000\.5' is not an integer$",
    ),
    (
        "--stiffness count_mismatch_K.mtx --mass M.mtx",
        2,
        r"^count_mismatch_K\.mtx:3: size line announces 6 entries but the file holds 5$",
    ),
    (
        "--stiffness huge_size_K.mtx --mass M.mtx",
        2,
        r"^huge_size_K\.mtx:2: matrix size 9223372036854775807 exceeds the 2147483647 equations",
    ),
    (
        "--stiffness empty_matrix_K.mtx --mass M.mtx",
        2,
        r"^empty_matrix_K\.mtx: a 0 x 0 matrix: the model has no dofs$",
    ),
    ("--stiffness nan_K.mtx --mass M.mtx", 2, r"^nan_K\.mtx:5: value nan is not a finite number$"),
    (
        "--stiffness complex_K.mtx --mass M.mtx",
        2,
        r"^complex_K\.mtx:1: complex matrix; mass, stiffness and damping must be real$",
    ),
    (
        "--stiffness both_triangles_K.mtx --mass M.mtx",
        2,
        r"^both_triangles_K\.mtx:6: entry \(2, 3\) lies above the diagonal but earlier entries "
        r"lie on the other side; a symmetric file stores one triangle only$",
    ),
    (
        "--stiffness nonsym_general_K.mtx --mass M.mtx",
        2,
        r"^nonsym_general_K\.mtx: matrix is not symmetric: entry \(1, 2\) = -1000\.0 but \(2, 1\) "
        r"= -900\.0; the difference 100 exceeds",
    ),
    ("--stiffness K.mtx --mass small_M.mtx", 2, r"^small_M\.mtx: matrix is 2 x 2 but K\.mtx is 3"),
    (
        "--stiffness K.mtx --mass M.mtx --dofs dofs_two_rows.csv",
        2,
        r"^dofs_two_rows\.csv: 2 dofs but K\.mtx is a 3 x 3 matrix$",
    ),
    (
        "--stiffness K.mtx --mass M.mtx --dofs dofs_bad_direction.csv",
        2,
        r"^dofs_bad_direction\.csv:4: unknown direction 'uw', expected one of ux uy uz rx ry rz q$",
    ),
    (
        "--stiffness K.mtx --mass M.mtx --dofs dofs.csv --nodes duplicate_nodes.csv",
        2,
        r"^duplicate_nodes\.csv:5: node 2 is listed twice \(first on line 3\)$",
    ),
    (
        "--stiffness K.mtx --mass M.mtx --dofs dofs.csv --constraints dangling_constraints.csv",
        2,
        r"^dangling_constraints\.csv:3: node 99 has no dofs in the model$",
    ),
    # a negative mass diagonal is a property of the numbers, found by the model validation
    (
        "--stiffness K.mtx --mass negative_mass_M.mtx",
        3,
        r"mass matrix is indefinite.*negative diagonal.*node 2",
    ),
    # Ansys MMF mapping
    (
        "--stiffness K.mtx --mass M.mtx --mapping temperature.mapping",
        2,
        r"^temperature\.mapping:3: dof TEMP is not structural",
    ),
    (
        "--stiffness K.mtx --mass M.mtx --mapping short.mapping",
        2,
        r"^K\.mtx: matrix is 3 x 3 but short\.mapping maps 2 equations$",
    ),
    (
        "--stiffness K.mtx --mass M.mtx --mapping comma_line.mapping",
        2,
        r"^comma_line\.mapping:3: expected 'equation node dof', got ','$",
    ),
    # the matrices of a constrained model with a mapping file: the order cannot be proved
    (
        "--stiffness K.mtx --mass M.mtx --mapping chain.mapping",
        2,
        r"^chain\.mapping: the equation order is not proved: K maps the rigid-body translation "
        r"in x to a residual of 1\.4e-01 \(at most 1e-06 for a free body\); .* or the model is "
        r"constrained",
    ),
    (
        "--stiffness K.mtx --mass M.mtx --mapping chain.mapping --nodes hand_edited.cdb",
        2,
        r"^hand_edited\.cdb:5: NBLOCK: x '2\.5000000000000E-00l' is not a number$",
    ),
    # MATLAB
    (
        "no_stiffness.mat",
        2,
        r"^no_stiffness\.mat: no stiffness matrix: the file holds M \(3x3 double\), B \(3x1 "
        r"double\); name it with --stiffness-name$",
    ),
    (
        "transposed_B.mat",
        2,
        r"^transposed_B\.mat: input matrix B is 1 x 3, expected 3 rows \(stored transposed\?",
    ),
    ("struct_K.mat", 2, r"^struct_K\.mat: variable K \(1x1 struct\) is a struct, not a matrix$"),
    (
        "ambiguous_C.mat",
        2,
        r"^ambiguous_C\.mat: variable C is 3 x 3 next to B: it may be the damping matrix",
    ),
    ("complex_K.mat", 2, r"^complex_K\.mat: variable K is complex; mass, stiffness, damping"),
    (
        "--format matlab plain_h5.mat",
        2,
        r"^plain_h5\.mat: an HDF5 file without MATLAB variables \(no MATLAB_class attributes\)",
    ),
    # Abaqus
    (
        "--stiffness nonsym_STIF1.mtx --mass good_MASS1.mtx",
        2,
        r"^nonsym_STIF1\.mtx:4: matrix is not symmetric: entry \(2:ux, 1:ux\) = -1500000\.0 but "
        r"the mirror entry on line 3 is -1000000\.0$",
    ),
    (
        "--stiffness good_STIF1.mtx --mass inf_MASS1.mtx",
        2,
        r"^inf_MASS1\.mtx:2: value inf is not a finite number$",
    ),
    (
        "--stiffness internal_node_STIF1.mtx --mass good_MASS1.mtx",
        2,
        r"^internal_node_STIF1\.mtx:3: node -1 is an internal node",
    ),
    (
        "--stiffness temperature_STIF1.mtx --mass good_MASS1.mtx",
        2,
        r"^temperature_STIF1\.mtx:3: dof 11 of node 1 is a temperature",
    ),
    (
        "--stiffness huge_label_STIF1.mtx --mass good_MASS1.mtx",
        2,
        r"^huge_label_STIF1\.mtx:2: row node '99999999999999999999' is out of range",
    ),
    (
        "--stiffness good_STIF1.mtx --mass good_MASS1.mtx --inp missing_node.inp",
        2,
        r"^good_STIF1\.mtx:2: node 2 is not defined in missing_node\.inp \(no \*NODE data line\)$",
    ),
    (
        "--stiffness good_STIF1.mtx --mass good_MASS1.mtx --damping structural_DMPS1.mtx",
        2,
        r"^structural_DMPS1\.mtx: a structural damping matrix \(DMPS\)",
    ),
    # Abaqus FORMAT=COORDINATE with the .inp (the equation order derived and proved)
    (
        "--stiffness cube_STIF1.mtx --mass cube_MASS1.mtx",
        2,
        r"^cube_STIF1\.mtx: FORMAT=COORDINATE files number the equations without node labels; "
        r"give the Abaqus input file as inp",
    ),
    (
        "--stiffness cube_STIF1.mtx --mass cube_MASS1.mtx --inp beams.inp",
        2,
        r"^cube_STIF1\.mtx: the equation order derived from beams\.inp gives 48 equations \(8 "
        r"nodes x ux uy uz rx ry rz from elements B31\) but the matrices have 24; give the dof of "
        r"every equation as dofs",
    ),
    (
        "--stiffness cube_STIF1.mtx --mass cube_MASS1.mtx --inp unknown_element.inp",
        2,
        r"^unknown_element\.inp:19: element type C3D4X is a type pymorembs does not know; "
        r"pymorembs cannot tell which equations Abaqus gives it$",
    ),
    (
        "--stiffness cube_STIF1.mtx --mass cube_MASS1.mtx --inp swapped_nodes.inp",
        2,
        r"^cube_STIF1\.mtx: the equation order derived from swapped_nodes\.inp does not fit the "
        r"matrices: rigid-body residual \S+ \(at most 1e-06 when order and coordinates belong",
    ),
    (
        "--stiffness good_STIF1.mtx --mass good_MASS1.mtx --inp two_instances.inp",
        2,
        r"^two_instances\.inp: nodes in 2 places \(instance bar-1 \(part bar\), instance bar-2 "
        r"\(part bar\)\): which labels Abaqus writes into FORMAT=MATRIX INPUT files",
    ),
    # Abaqus substructure matrices (*SUBSTRUCTURE MATRIX OUTPUT)
    (
        "cut_substructure.mtx",
        2,
        r"^cut_substructure\.mtx:10: \*MATRIX, TYPE=STIFFNESS block holds 3 of the 6 values of "
        r"the lower triangle of 3 equations; is the file cut\?$",
    ),
    (
        "unsym_substructure.mtx",
        2,
        r"^unsym_substructure\.mtx:9: \*MATRIX, TYPE=STIFFNESS \(stored full\) is not symmetric: "
        r"entry \(7:ux, 9:uz\) = 500\.0 but \(9:uz, 7:ux\) = 600\.0; pymorembs needs symmetric",
    ),
    (
        "stiffness_only_substructure.mtx",
        2,
        r"^stiffness_only_substructure\.mtx: the file holds only the stiffness matrix \(no "
        r"\*MATRIX, TYPE=MASS block\)",
    ),
    # Nastran DMIG, bulk data and punches without matrices
    (
        "no_mass.pch",
        2,
        r"^no_mass\.pch: holds KAAX \(stiffness\) but no mass matrix \(no MAAX\); export the "
        r"mass matrix too or name it with --mass-name$",
    ),
    ("complex.pch", 2, r"^complex\.pch:1: DMIG KAAX is complex \(TIN=3\); a real matrix is needed"),
    (
        "scalar_and_grid.pch",
        2,
        r"^scalar_and_grid\.pch: point 9001 appears as a scalar point \(component 0\) and as a "
        r"grid \(components 1-6\)$",
    ),
    (
        "nonsym.pch",
        2,
        r"^nonsym\.pch:7: matrix is not symmetric: entry \(101:ux, 102:ux\) = -1200\.0 but the "
        r"mirror entry on line 5 is -1000\.0$",
    ),
    ("huge_grid.pch", 2, r"^huge_grid\.pch:2: column grid GJ \(field 3\) '9+' is out of range"),
    (
        "good.pch --nodes duplicate_grid.bdf",
        2,
        r"^duplicate_grid\.bdf:4: GRID 101 is defined twice with different data \(first in "
        r"duplicate_grid\.bdf:2\)$",
    ),
    (
        "two_pairs.pch",
        2,
        r"^two_pairs\.pch: holds several stiffness/mass pairs: KAAX/MAAX, KGG/MGG; choose one "
        r"with --stiffness-name and --mass-name$",
    ),
    (
        "results.pch",
        2,
        r"^results\.pch: holds no DMIG matrices: a results punch \(\$EIGENVECTOR, 2 modes of a "
        r"normal modes analysis\); write the matrices with PARAM,EXTOUT,DMIGPCH$",
    ),
    (
        "extbulk.pch",
        2,
        r"^extbulk\.pch: holds no DMIG matrices: Nastran bulk data \(EXTRN, 2 GRID, 2 ASET, "
        r"SPOINT\): the EXTBULK of external superelement 7; its matrices are in the OP4 file",
    ),
    (
        "good.pch --nodes cd_partial.bdf",
        2,
        r"^good\.pch: grid 102 has CD=5 and only components 1 of its translations in the "
        r"matrices; its local axes mix the basic directions",
    ),
    (
        "good.pch --nodes cord_loop.bdf",
        2,
        r"^cord_loop\.bdf:2: coordinate systems refer to each other: 5 -> 6 -> 5$",
    ),
    # Nastran OP4 and OP2
    (
        "kgg_only.op4",
        2,
        r"^kgg_only\.op4: holds KGG \(stiffness, 2 x 2\) but no mass matrix \(no MGG\)",
    ),
    (
        "body.op4 --dofs seqgp.bdf",
        2,
        r"^seqgp\.bdf:3: SEQGP resequences the points, so the row order of the matrices is not "
        r"the ascending ids",
    ),
    (
        "truncated.op2",
        2,
        r"^truncated\.op2: cannot read the OP2 file \(truncated, damaged or not an OP2 file\)",
    ),
    (
        "body.op4 --dofs op4_dofs_three.csv",
        2,
        r"^op4_dofs_three\.csv: 3 dofs but matrix KAAX in body\.op4 is 2 x 2$",
    ),
    (
        "dense_huge.op4 --dofs op4_dofs.csv",
        2,
        r"^dense_huge\.op4:1: matrix KAAX is 50000 x 50000 in dense format, 18\.6 GiB in memory; "
        r"write it in sparse format",
    ),
    (
        "truncated.op4 --dofs op4_dofs.csv",
        2,
        r"^truncated\.op4: cannot read the OP4 file \(truncated, damaged or not an OP4 file\)",
    ),
]


#: Valid files that the broken ones are combined with.
HELPERS = {"K.mtx", "M.mtx", "dofs.csv", "good_MASS1.mtx", "good_STIF1.mtx", "good.pch"}
HELPERS |= {"op4_dofs.csv", "body.op4", "cube_STIF1.mtx", "cube_MASS1.mtx"}


def _ids() -> list[str]:
    """Each case is named by its broken file."""
    names = []
    for argv, _, _ in CASES:
        files = [word for word in argv.split() if "." in word]
        names.append(next((f for f in files if f not in HELPERS), files[0]))
    return names


@pytest.fixture
def in_corpus(monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.chdir(FILES)
    return FILES


@pytest.mark.parametrize(("argv", "code", "pattern"), CASES, ids=_ids())
def test_broken_file_gives_one_line(
    argv: str, code: int, pattern: str, in_corpus: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    exit_code = main(["info", *argv.split(), "--modes", "1"])
    out, err = capsys.readouterr()
    assert exit_code == code, err
    assert out == ""
    assert "Traceback" not in err
    assert err.endswith("\n") and err.count("\n") == 1, err
    assert err.startswith("pymorembs: error: "), err
    message = err[len("pymorembs: error: ") : -1]
    assert re.search(pattern, message), message


def test_the_corpus_is_used_and_large_enough() -> None:
    """Every file of the corpus appears in some case; at least 18 deliberately broken files."""
    used = {word for argv, _, _ in CASES for word in argv.split() if "." in word}
    files = {path.name for path in FILES.iterdir()}
    assert files <= used, sorted(files - used)
    assert used <= files, sorted(used - files)
    assert len(files - HELPERS) >= 18


@pytest.mark.parametrize(
    ("argv", "code", "pattern"),
    [case for case in CASES if case[0] in ("garbage.pch", "cut.full", "complex.pch")],
)
def test_real_process(argv: str, code: int, pattern: str) -> None:
    """The installed command in a separate process: exit code, one line, no traceback."""
    command = [
        sys.executable,
        "-c",
        "import sys; from pymorembs.job.cli import main; sys.exit(main())",
    ]
    done = subprocess.run(
        [*command, "info", *argv.split()],
        cwd=FILES,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert done.returncode == code, done.stderr
    assert done.stdout == ""
    lines = done.stderr.splitlines()
    assert len(lines) == 1 and "Traceback" not in done.stderr, done.stderr
    assert re.search(pattern, lines[0].removeprefix("pymorembs: error: ")), lines[0]
