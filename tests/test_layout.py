"""The house's imports run one way, downward (CONTRIBUTING.md), and its functions stay short.

Every import of the solver and the add-on, module-level or inside a
function, is read from the source: no module may import itself through a
circle, and no module may import a stage above its own.
"""

import ast
import subprocess
import sys
from graphlib import CycleError, TopologicalSorter
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

# Rank of each part of the house: a module may import its own part or a
# lower one.  Top-level solver modules not listed take the rank of pipeline.
RANKS = {
    "solver.errors": 0,
    "solver.checks": 0,
    "solver.stages": 0,  # running named stages: any pipeline's, so it knows none
    "solver.linalg": 1,
    "solver.surface": 2,
    "solver.network": 3,
    "solver.mesh": 4,
    "solver.field": 5,
    "solver.analysis": 6,
    # a stage after the field (CONTRIBUTING: "Where a new piece goes"): it
    # takes the field's arrays (field/matchings.py), not a Result, so the
    # pipeline above can run it
    "solver.hexmesh": 7,
    "solver.examples": 8,
    "solver.pipeline": 8,
    "solver.io": 9,
    "solver": 9,
    "solver.__main__": 10,
    "symframes_addon": 11,
    "testkit": 12,  # test and bench tools: nothing that ships imports them
}


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def sources() -> dict[str, Path]:
    files = [*ROOT.glob("solver/**/*.py"), *ROOT.glob("symframes_addon/**/*.py"), *ROOT.glob("testkit/**/*.py")]
    return {module_name(p): p for p in files}


def imports_of(name: str, path: Path, known: set[str]) -> set[str]:
    """The project modules that the module imports (absolute or relative)."""
    is_pkg = path.name == "__init__.py"
    package = name if is_pkg else name.rpartition(".")[0]
    out = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            # 'from pkg import mod' names a module when pkg.mod exists
            targets = [f"{mod}.{a.name}" if f"{mod}.{a.name}" in known else mod for a in node.names]
        else:
            continue
        for t in targets:
            while t and t not in known:
                t = t.rpartition(".")[0]
            if t and t != name:
                out.add(t)
    return out


def rank(name: str) -> int:
    best = None
    for prefix in RANKS:
        if name == prefix or (prefix != "solver" and name.startswith(prefix + ".")):
            if best is None or len(prefix) > len(best):
                best = prefix
    return RANKS[best] if best is not None else RANKS["solver.pipeline"]


def graph() -> dict[str, set[str]]:
    src = sources()
    known = set(src)
    return {name: imports_of(name, path, known) for name, path in src.items()}


def test_the_reader_sees_the_imports():
    g = graph()
    assert "solver.field.volume3d" in g["solver.pipeline"]
    assert {"solver.stages", "solver.mesh.meshing", "solver.field.meshed_boundary", "solver.field.root"} <= \
        g["solver.pipeline"]
    assert "solver.field.matchings" in g["solver.io.interchange"]
    assert "solver.mesh.tetwild" in g["testkit.tetedge"]
    assert "solver.linalg.pcg" in g["solver.field.volume3d"]
    assert "solver.pipeline" in g["solver"]
    assert "solver" in g["symframes_addon.operators"]  # the public API (tests/test_addon_imports.py)
    assert "solver.precheck" in g["solver"]


def test_no_import_circles():
    g = graph()
    try:
        list(TopologicalSorter(g).static_order())
    except CycleError as e:
        raise AssertionError(f"import circle: {' -> '.join(e.args[1])}") from None


def test_imports_run_downward():
    g = graph()
    upward = sorted(f"{a} (rank {rank(a)}) imports {b} (rank {rank(b)})"
                    for a, deps in g.items() for b in deps if rank(b) > rank(a))
    assert not upward, "imports that run upward:\n" + "\n".join(upward)


def test_the_solver_never_imports_bpy():
    g = sources()
    for name, path in g.items():
        if not name.startswith("solver"):
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            mods = ([a.name for a in node.names] if isinstance(node, ast.Import) else
                    [node.module or ""] if isinstance(node, ast.ImportFrom) and not node.level else [])
            assert not any(m.split(".")[0] in ("bpy", "mathutils", "symframes_addon", "testkit", "bench", "tests")
                           for m in mods), name
    out = subprocess.run([sys.executable, "-c", "import sys, solver, solver.io, solver.__main__; "
                          "print('bpy' in sys.modules)"], cwd=ROOT, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_errors_doc_lists_every_refusal_class():
    """docs/errors.md has a row, with an example message, for every error
    class of solver.errors (issue 43)."""
    import inspect
    import pathlib
    import re

    import solver.errors as errors

    doc = (pathlib.Path(__file__).resolve().parents[1] / "docs" / "errors.md").read_text(encoding="utf-8")
    rows = {m.group(1): m.group(0) for m in re.finditer(r"^\| `(\w+)`[^\n]*$", doc, re.M)}
    for name, cls in inspect.getmembers(errors, inspect.isclass):
        if issubclass(cls, (errors.SymFramesError, errors.Cancelled)) and cls is not errors.SymFramesError:
            assert name in rows, f"docs/errors.md has no row for {name}"
            assert name == "Cancelled" or rows[name].count("`") >= 4, f"{name}: no example message"


def test_functions_stay_short_and_the_pipeline_keeps_only_the_order():
    """No function or method in solver/ is over 120 lines, and FieldProblem
    (the stages' order and the LM set-up) stays within 200 (issue 42): a
    long one is split into named steps."""
    long, problem = [], None
    for path in sorted((ROOT / "solver").rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            n = getattr(node, "end_lineno", 0) - getattr(node, "lineno", 0) + 1
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and n > 120:
                long.append(f"{path.relative_to(ROOT)}:{node.lineno} {node.name} ({n} lines)")
            if isinstance(node, ast.ClassDef) and node.name == "FieldProblem":
                problem = n
    assert not long, long
    assert problem is not None and problem <= 200, problem


def test_each_package_names_its_modules():
    """The docstring of each package's __init__.py names every module of the
    package (by its stem, "meshing" or "meshing.py"): the floor plan a reader
    opens first lists every room."""
    import re

    missing = {}
    for init in sorted((ROOT / "solver").glob("*/__init__.py")):
        doc = ast.get_docstring(ast.parse(init.read_text(encoding="utf-8"), str(init))) or ""
        stems = sorted(p.stem for p in init.parent.glob("*.py") if p.name != "__init__.py")
        absent = [s for s in stems if not re.search(rf"\b{re.escape(s)}(\.py)?\b", doc)]
        if absent:
            missing[str(init.parent.relative_to(ROOT))] = absent
    assert not missing, "package docstrings that do not name their modules:\n" + "\n".join(
        f"{pkg}/__init__.py: {', '.join(stems)}" for pkg, stems in missing.items())


def test_only_the_pipeline_reads_a_results_problem():
    """No file of the solver or the add-on but solver/pipeline.py reads into
    a Result's problem (the text ``.problem.``): what a caller needs of a
    solve is a field of the Result."""
    offenders = []
    for path in sorted([*(ROOT / "solver").rglob("*"), *(ROOT / "symframes_addon").rglob("*")]):
        if not path.is_file() or "__pycache__" in path.parts or path == ROOT / "solver" / "pipeline.py":
            continue
        text = path.read_bytes().decode("utf-8", errors="replace")
        offenders += [f"{path.relative_to(ROOT)}:{i}: {line.strip()}"
                      for i, line in enumerate(text.splitlines(), 1) if ".problem." in line]
    assert not offenders, "reads into a Result's problem outside solver/pipeline.py:\n" + "\n".join(offenders)
