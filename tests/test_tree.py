"""The tests run from any checkout: no test reaches a file by an absolute path (issue #16)."""

from __future__ import annotations

import re
import types
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


ROOT = TESTS.parent
SOURCE = ROOT / "src" / "pymorembs"


def public_modules() -> set[str]:
    """The public surface as ``docs/api.md`` documents it: the modules of the table of its
    section "The public surface"."""
    text = (ROOT / "docs" / "api.md").read_text(encoding="utf-8")
    section = text.split("\n## The public surface\n", 1)[1].split("\n## ", 1)[0]
    return set(re.findall(r"^\| `(pymorembs(?:\.\w+)?)` \|", section, flags=re.M))


def non_public_imports(source: str, public: set[str]) -> list[str]:
    """The imports of ``source`` (a module of the job layer) that reach past the public surface:
    a module not in ``public`` (the job layer's own modules aside), or a name not in the
    ``__all__`` of a public module (nor a public module itself)."""
    import ast
    import importlib

    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            modules = [alias.name for alias in node.names]
            found += [
                m
                for m in modules
                if m.startswith("pymorembs")
                and m not in public
                and m.split(".")[:2] != ["pymorembs", "job"]
            ]
        elif isinstance(node, ast.ImportFrom):
            module = node.module or ""
            if node.level > 1:
                found.append(f"{'.' * node.level}{module} (relative, outside the job layer)")
                continue
            if node.level == 1 or module == "pymorembs.job" or module.startswith("pymorembs.job."):
                continue  # the job layer's own modules
            if not module.startswith("pymorembs"):
                continue
            if module not in public:
                found.append(module)
                continue
            exported = set(getattr(importlib.import_module(module), "__all__", ()))
            for alias in node.names:
                name = f"{module}.{alias.name}"
                if alias.name not in exported and name not in public:
                    found.append(name)
    return found


def test_the_job_layer_imports_only_the_public_api():
    """Issue #16: "a job layer on top that imports only the public API" -- the modules and names
    of docs/api.md's public surface, nothing from the modules behind them."""
    public = public_modules()
    found = []
    for path in sorted((SOURCE / "job").glob("*.py")):
        found += [f"job/{path.name}: {m}" for m in non_public_imports(path.read_text(), public)]
    assert found == []


def test_the_check_of_the_job_layer_finds_what_it_is_for():
    public = public_modules()
    assert {"pymorembs", "pymorembs.analysis", "pymorembs.methods"} <= public
    assert non_public_imports("from pymorembs.analysis.reference import choose_kind", public) == [
        "pymorembs.analysis.reference"
    ]
    assert non_public_imports("import pymorembs.linalg.backends", public) == [
        "pymorembs.linalg.backends"
    ]
    assert non_public_imports("from pymorembs.analysis import SETTLE_ROUNDS", public) == [
        "pymorembs.analysis.SETTLE_ROUNDS"  # in the module behind, not in __all__
    ]
    assert non_public_imports("from .. import api", public) == [
        ".. (relative, outside the job layer)"
    ]
    fine = (
        "from pymorembs import reduce, progress\nfrom pymorembs.analysis import choose_kind\n"
        "from pymorembs.job.schema import Job\nfrom . import run\nimport numpy"
    )
    assert non_public_imports(fine, public) == []


def test_every_public_module_says_what_it_offers():
    """Each public module has an ``__all__`` whose names it holds, and docs/api.md's table and
    the modules agree."""
    import importlib

    public = public_modules()
    assert len(public) >= 10
    for name in sorted(public):
        module = importlib.import_module(name)
        exported = getattr(module, "__all__", None)
        assert exported, f"{name} has no __all__"
        missing = [item for item in exported if not hasattr(module, item)]
        assert missing == [], (name, missing)


#: The layers of the library from the ground up (issue #28): a module imports from its own
#: layer and the ones below it, never from a layer above, also not lazily inside a function. A
#: module stands on the layer of the longest name here that it is or lies under (``pymorembs``
#: itself, the package's top level, names only itself). The saved reduced body
#: (``io.reduced_file``) is a file of what the methods make, so it stands above them, with the
#: exports; every other reader and writer of ``io`` stands below ``preparation``, which reads
#: matrices and meshes through them. The method registry (``methods``: the options and their one
#: check) stands low, so that the algorithms of ``reduction`` take its checked options.
LAYERS: tuple[tuple[str, ...], ...] = (
    ("errors", "arrays", "display", "progress", "sparse_rows", "arguments", "frequencies", "kinds"),
    ("methods",),
    ("linalg", "elements", "parallel"),
    ("surface", "system"),
    ("body",),
    ("stress",),
    ("io", "units"),
    ("preparation", "examples"),
    ("reduction",),
    ("io.reduced_file", "export"),
    ("analysis",),
    ("report",),
    ("api", ""),
    ("job",),
)
#: What a lower layer may take from the package's top level: the version, which
#: ``pymorembs/__init__.py`` defines before it imports anything (the writers stamp files with it).
TOP_LEVEL_METADATA = {"__version__"}


def layer_of(module: str) -> int | None:
    """The layer of ``module`` (``pymorembs...``), or None where no entry of LAYERS names it."""
    best, found = -1, None
    for number, names in enumerate(LAYERS):
        for name in names:
            full = f"pymorembs.{name}" if name else "pymorembs"
            named = module == full or (name != "" and module.startswith(full + "."))
            if named and len(full) > best:
                best, found = len(full), number
    return found


def module_name(path: Path) -> str:
    parts = path.relative_to(SOURCE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imported_modules(module: str, source: str, is_package: bool = False) -> list[str]:
    """Every ``pymorembs`` module that ``source`` (the text of ``module``) imports, at its top
    or inside a function; relative imports resolved; an import of only the top level's
    metadata (``from pymorembs import __version__``) left out."""
    import ast

    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            found += [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            name = node.module or ""
            if node.level:
                package = module.split(".")
                package = package if is_package else package[:-1]
                base = package[: len(package) - (node.level - 1)]
                name = ".".join([*base, name] if name else base)
            names = {alias.name for alias in node.names}
            if name == "pymorembs" and names <= TOP_LEVEL_METADATA:
                continue
            found.append(name)
    return [name for name in found if name == "pymorembs" or name.startswith("pymorembs.")]


def climbs(module: str, source: str, is_package: bool = False) -> list[str]:
    """The imports of ``module`` that reach a layer above its own, and any module LAYERS does not
    place."""
    own = layer_of(module)
    if own is None:
        return [f"{module}: not on any layer of LAYERS"]
    found = []
    for target in imported_modules(module, source, is_package):
        layer = layer_of(target)
        if layer is None:
            found.append(f"{module} -> {target}: not on any layer of LAYERS")
        elif layer > own:
            found.append(f"{module} (layer {own}) -> {target} (layer {layer})")
    return found


def test_no_module_imports_from_a_layer_above_its_own():
    """Issue #28: no climb from a lower layer into a higher one (analysis -> report, the methods
    -> analysis ...), lazy imports included."""
    found = []
    for path in sorted(SOURCE.rglob("*.py")):
        name = module_name(path)
        found += climbs(name, path.read_text(encoding="utf-8"), path.name == "__init__.py")
    assert found == []


def test_the_layer_check_finds_what_it_is_for():
    assert layer_of("pymorembs.io.reduced_file") > layer_of("pymorembs.reduction.krylov")
    assert layer_of("pymorembs.io.matrix_market") < layer_of("pymorembs.preparation.stiffening")
    assert layer_of("pymorembs") == layer_of("pymorembs.api") < layer_of("pymorembs.job.app")
    assert layer_of("pymorembs.nothing") is None
    lazy = "def f():\n    from pymorembs.report.time_plots import plot_large_motion\n"
    assert climbs("pymorembs.analysis.large_motion", lazy) == [
        "pymorembs.analysis.large_motion (layer 10) -> pymorembs.report.time_plots (layer 11)"
    ]
    assert climbs("pymorembs.reduction.soaga", "import pymorembs.analysis.error as e") != []
    assert climbs("pymorembs.export.sid", "from pymorembs import __version__") == []
    assert climbs("pymorembs.export.sid", "from pymorembs import __version__, reduce") != []
    relative = "from .matrices import reduced_arrays\nfrom . import sid\nfrom .. import body\n"
    assert imported_modules("pymorembs.export.outputs", relative) == [
        "pymorembs.export.matrices",
        "pymorembs.export",
        "pymorembs",
    ]
    assert imported_modules("pymorembs.export", "from .sid import write_sid", is_package=True) == [
        "pymorembs.export.sid"
    ]


#: Calls that build or run an Exudyn system; a module that only writes files makes none.
SIMULATION_CALLS = {"SystemContainer", "AddSystem", "Assemble", "SolveDynamic", "SolveStatic"}


def simulation_in(source: str) -> list[str]:
    """What in ``source`` simulates: an import of Exudyn or of the analysis (where the Exudyn
    model and its simulator live), or a call of :data:`SIMULATION_CALLS`."""
    import ast

    found = []
    for node in ast.walk(ast.parse(source)):
        modules = []
        if isinstance(node, ast.Import):
            modules = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            modules = [node.module or ""]
        for module in modules:
            if module.split(".")[0] == "exudyn" or module.startswith("pymorembs.analysis"):
                found.append(f"import {module}")
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute):
            if node.func.attr in SIMULATION_CALLS:
                found.append(f"{node.func.attr}()")
    return found


def test_the_export_writes_files_and_simulates_nothing():
    """Issue #28: the Exudyn model builder and simulator live in analysis/, not in export/."""
    found = []
    for path in sorted((SOURCE / "export").rglob("*.py")):
        found += [f"export/{path.name}: {what}" for what in simulation_in(path.read_text())]
    assert found == []


def test_the_simulation_check_finds_what_it_is_for():
    source = (
        "def run(model):\n    import exudyn\n    model.mbs.Assemble()\n"
        "    model.mbs.SolveDynamic(settings)\n"
        "from pymorembs.analysis.exudyn_model import simulate_exudyn\n"
    )
    assert simulation_in(source) == [
        "import pymorembs.analysis.exudyn_model",
        "import exudyn",
        "Assemble()",
        "SolveDynamic()",
    ]
    assert simulation_in("from pymorembs.export.deterministic import write_npz") == []


def export_kind_lists(source: str, kinds: set[str]) -> list[int]:
    """The lines of the literal lists, tuples and sets of ``source`` (Python) that hold two or
    more of the export ``kinds``."""
    import ast

    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.List | ast.Tuple | ast.Set):
            named = {e.value for e in node.elts if isinstance(e, ast.Constant)} & kinds
            if len(named) >= 2:
                found.append(node.lineno)
    return found


def string_kinds(source: str, kinds: set[str]) -> set[str]:
    """The export ``kinds`` that ``source`` (Python) holds as a string of their own."""
    import ast

    return {n.value for n in ast.walk(ast.parse(source)) if isinstance(n, ast.Constant)} & kinds


def quoted_kinds(text: str, kinds: set[str]) -> set[str]:
    """The export ``kinds`` that ``text`` names as a quoted string (``"sid"``, ``'sid'``)."""
    return {kind for kind in kinds if re.search(rf"""(["'`]){kind}\1""", text)}


def test_no_list_of_export_kinds_outside_the_registry():
    """Issue #28 item 3: the kinds of ``[export] outputs`` are written once, in
    ``export/registry.py``: no other module holds a list of them, ``write_outputs`` names none
    (a loop over the registry, no if-chain), and no static file of the app lists them (the page
    builds its list from what the server serves)."""
    from pymorembs.export import EXPORT_KINDS

    kinds = set(EXPORT_KINDS)
    found = []
    for path in sorted(SOURCE.rglob("*.py")):
        if path.relative_to(SOURCE).as_posix() != "export/registry.py":
            lines = export_kind_lists(path.read_text(encoding="utf-8"), kinds)
            found += [f"{path.relative_to(SOURCE)}:{line}" for line in lines]
    outputs = (SOURCE / "export" / "outputs.py").read_text(encoding="utf-8")
    found += [f"export/outputs.py names {kind!r}" for kind in sorted(string_kinds(outputs, kinds))]
    for path in sorted((SOURCE / "job" / "app" / "static").iterdir()):
        named = quoted_kinds(path.read_text(encoding="utf-8"), kinds)
        if len(named) >= 2:
            found.append(f"{path.relative_to(SOURCE)} lists {sorted(named)}")
    assert found == []


def test_the_check_of_export_kinds_finds_what_it_is_for():
    kinds = {"npz", "mtx", "sid"}
    assert export_kind_lists('KINDS = ("npz", "mtx")\nx = ["sid"]\ny = {"a", "sid"}', kinds) == [1]
    assert export_kind_lists('if "npz" in outputs and "sid" in outputs: pass', kinds) == []
    assert string_kinds('"""Writes ``sid``."""\nif "npz" in outputs: pass', kinds) == {"npz"}
    assert quoted_kinds('<input value="sid"> kinds: ["npz", \'mtx\'] npzfile', kinds) == kinds
    assert quoted_kinds("reduced.npz and the sid file", kinds) == set()


def shadowed_modules(package: types.ModuleType) -> list[str]:
    """The modules and subpackages of ``package`` whose name the package's top level binds to
    something else (``import package.name as x`` would give that, not the module)."""
    import pkgutil

    return [
        info.name
        for info in pkgutil.iter_modules(package.__path__)
        if hasattr(package, info.name)
        and not isinstance(getattr(package, info.name), types.ModuleType)
    ]


def test_no_name_of_the_top_level_shadows_a_module():
    """Issue #28: the steps of a preparation live in ``pymorembs.preparation``; ``pm.prepare``
    is the function, and no name of the top level hides a module of the package."""
    import pymorembs
    import pymorembs.preparation as preparation

    assert isinstance(preparation, types.ModuleType)
    assert preparation.__name__ == "pymorembs.preparation"
    assert callable(pymorembs.prepare) and not isinstance(pymorembs.prepare, types.ModuleType)
    assert pymorembs.prepare.__module__ == "pymorembs.api"
    assert shadowed_modules(pymorembs) == []


def test_the_shadow_check_finds_what_it_is_for(tmp_path):
    package = types.ModuleType("package")
    package.__path__ = [str(tmp_path)]
    (tmp_path / "steps.py").write_text("")
    (tmp_path / "tools.py").write_text("")
    (tmp_path / "other.py").write_text("")
    package.steps = lambda: None  # a function named like the module: shadowed
    package.tools = types.ModuleType("package.tools")  # the module itself: fine
    assert shadowed_modules(package) == ["steps"]


def design_layers(text: str) -> list[tuple[str, ...]]:
    """The layers as the table of the section "The layers" of ``docs/design.md`` lists them:
    the module names in backticks of each row, the package's top level as ``""``."""
    section = text.split("\n## The layers\n", 1)[1].split("\n## ", 1)[0]
    rows = re.findall(r"^\| \d+ \| (.*?) \|", section, flags=re.M)
    top = ("",)  # the package's top level, named in words
    return [
        tuple(re.findall(r"`([\w.]+)`", row)) + (top if "top level" in row else ()) for row in rows
    ]


def test_the_design_page_lists_the_layers_of_the_tree():
    """docs/design.md draws the layers that LAYERS holds, in its order."""
    text = (ROOT / "docs" / "design.md").read_text(encoding="utf-8")
    assert design_layers(text) == [tuple(names) for names in LAYERS]


def named_kinds(text: str, kinds: set[str]) -> set[str]:
    """The ``kinds`` that a static file (HTML, JavaScript, CSS) names as a value of its own: a
    quoted string (``"rigid"``), the text of an element (``<option>rigid</option>``) or an
    object key (``rigid: [...]``)."""
    return {
        kind
        for kind in kinds
        if re.search(rf"""(["'`]){kind}\1|>\s*{kind}\s*<|(?<![\w.-]){kind}\s*:(?!:)""", text)
    }


def test_no_list_of_job_kinds_in_the_static_files():
    """Issue #28 item 1: the frame types, damping, interface and reference kinds (with their
    parameters) are written once, in ``pymorembs/kinds.py``; the page builds its lists and
    forms from the schema the server serves (``GET /api/schema``), no static file lists them."""
    from pymorembs.kinds import DampingKind, FrameType, InterfaceKind, ReferenceKind

    found = []
    for path in sorted((SOURCE / "job" / "app" / "static").iterdir()):
        text = path.read_text(encoding="utf-8")
        for family in (FrameType, DampingKind, InterfaceKind, ReferenceKind):
            named = named_kinds(text, set(family.names()))
            if len(named) >= 2:
                found.append(f"{path.relative_to(SOURCE)} lists {family.__name__} {sorted(named)}")
    assert found == []


def test_the_check_of_job_kinds_finds_what_it_is_for():
    kinds = {"rigid", "beams", "springs"}
    assert named_kinds("<select><option>rigid</option><option>beams</option></select>", kinds) == {
        "rigid",
        "beams",
    }
    assert named_kinds('const P = { beams: ["a"], springs: [] }; x === "rigid"', kinds) == kinds
    assert (
        named_kinds("light stiff beams and rigid links; a.beams: 1; display: none", kinds) == set()
    )
