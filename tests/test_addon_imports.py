"""The add-on reaches the solver only through its public API (CONTRIBUTING.md).

Every module of symframes_addon/ is parsed (module-level and function-level
imports alike): it may import the package ``solver`` itself and the names it
exports, ``solver.io`` and the names it exports, and ``solver.examples``;
no other solver module.  A rule the add-on needs belongs in the solver,
behind a public name.
"""

import ast
from pathlib import Path

import solver
import solver.io

ROOT = Path(__file__).resolve().parents[1]
PUBLIC = {"solver": set(solver.__all__) | {"io", "examples"}, "solver.io": set(solver.io.__all__),
          "solver.examples": None}  # None: any name of the module


def solver_imports(source: str, module: str) -> list[tuple[str, str | None]]:
    """(solver module, imported name or None) of every import of the solver
    in the source of the add-on module ``module`` (e.g. 'symframes_addon.job')."""
    package = module.rpartition(".")[0].split(".")
    out = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            out += [(a.name, None) for a in node.names if a.name.split(".")[0] == "solver"]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[: len(package) - (node.level - 1)]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            if mod.split(".")[0] != "solver":
                # 'from .. import solver' names the package itself
                out += [("solver", None) for a in node.names if not mod and a.name == "solver"]
                continue
            out += [(mod, a.name) for a in node.names]
    return out


def violations(source: str, module: str) -> list[str]:
    bad = []
    for mod, name in solver_imports(source, module):
        if mod not in PUBLIC:
            bad.append(f"{module} imports {mod}" + (f".{name}" if name else ""))
        elif name is not None and PUBLIC[mod] is not None and name not in PUBLIC[mod]:
            bad.append(f"{module} imports {name} from {mod}, which does not export it")
    return bad


def addon_modules() -> dict[str, Path]:
    return {".".join(p.relative_to(ROOT).with_suffix("").parts): p for p in ROOT.glob("symframes_addon/**/*.py")}


def test_the_check_sees_what_it_must_refuse():
    job = "symframes_addon.job"
    assert violations("from ..solver.analysis.measures import normal_adaptation", job) == [
        "symframes_addon.job imports solver.analysis.measures.normal_adaptation"]
    assert violations("def f():\n    from ..solver.network.intake import repairs_text\n", job)
    assert violations("import solver.mesh.tetmesh", job)
    assert violations("from ..solver import _Stages", job)
    assert violations("from ..solver.io.interchange import field_data", job)
    assert violations("from ..solver.io import interchange", job)
    assert not violations("from ..solver import check, FrameField\nfrom ..solver.io import export_field\n"
                          "from ..solver.examples import EXAMPLES\nfrom .. import solver\nfrom . import storage", job)


def test_the_addon_imports_only_the_public_api():
    modules = addon_modules()
    assert "symframes_addon.operators" in modules and len(modules) >= 10
    bad = [v for name, path in sorted(modules.items()) for v in violations(path.read_text(), name)]
    assert not bad, "the add-on reaches past the solver's public API:\n" + "\n".join(bad)

