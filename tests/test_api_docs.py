"""The API reference: every public name has a numpy-style docstring, and
the reference builds without a warning (scripts/build_docs.py, which
``./dev.sh docs`` runs).  Running it here keeps it from rotting."""

import importlib.util
import inspect
from pathlib import Path

import pytest

import solver
import solver.io

ROOT = Path(__file__).resolve().parent.parent


def _public():
    for mod in (solver, solver.io):
        for name in mod.__all__:
            yield f"{mod.__name__}.{name}", getattr(mod, name)


def _sections(doc: str) -> set[str]:
    lines = doc.splitlines()
    return {lines[i].strip() for i in range(len(lines) - 1)
            if lines[i + 1].strip() and set(lines[i + 1].strip()) == {"-"}
            and len(lines[i + 1].strip()) >= len(lines[i].strip()) > 0}


def _needs(obj) -> list[set[str]]:
    """The sections a name's docstring must have (any one of each set)."""
    if inspect.isclass(obj):
        if issubclass(obj, BaseException):
            return []  # an error class: its docstring says when it is raised
        return [{"Parameters", "Attributes"}]
    if callable(obj):
        sig = inspect.signature(obj)
        need = []
        if sig.parameters:
            need.append({"Parameters"})
        if sig.return_annotation not in (None, "None"):
            need.append({"Returns"})
        return need
    return []  # a constant: a docstring of its module


@pytest.mark.parametrize("qualname,obj", list(_public()), ids=[q for q, _ in _public()])
def test_public_name_has_numpy_docstring(qualname, obj):
    if not (inspect.isclass(obj) or callable(obj)):
        return
    doc = inspect.getdoc(obj) or ""
    assert len(doc) > 20, f"{qualname} has no docstring"
    have = _sections(doc)
    for alternatives in _needs(obj):
        assert have & alternatives, f"{qualname}: docstring lacks a {' or '.join(sorted(alternatives))} section"
    if inspect.isroutine(obj) and "Parameters" in have:
        documented = _documented_parameters(doc)
        for p in inspect.signature(obj).parameters.values():
            name = ("**" if p.kind is p.VAR_KEYWORD else "*" if p.kind is p.VAR_POSITIONAL else "") + p.name
            assert name in documented, f"{qualname}: parameter {name!r} is not documented"


def _documented_parameters(doc: str) -> set[str]:
    """Names in the Parameters section ("a : int", "a, b : float", "**kw")."""
    lines = doc.split("Parameters", 1)[1].splitlines()[2:]
    names = set()
    for i, line in enumerate(lines):
        if i + 1 < len(lines) and lines[i + 1].strip() and set(lines[i + 1].strip()) == {"-"}:
            break  # the next section
        if line and not line[0].isspace():
            names |= {n.strip() for n in line.split(" :")[0].split(",")}
    return names


def test_reference_builds_without_warnings(tmp_path):
    spec = importlib.util.spec_from_file_location("build_docs", ROOT / "scripts" / "build_docs.py")
    build_docs = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(build_docs)
    pages = build_docs.build(tmp_path)
    names = {p.relative_to(tmp_path).as_posix() for p in pages}
    assert {"solver.html", "solver/io.html", "solver/examples.html"} <= names
    html = (tmp_path / "solver.html").read_text()
    for qualname, _ in _public():
        if qualname.startswith("solver.") and qualname.count(".") == 1:
            assert f'id="{qualname.split(".")[1]}"' in html, f"{qualname} missing from the reference"
    io_html = (tmp_path / "solver" / "io.html").read_text()
    for name in solver.io.__all__:
        assert f'id="{name}"' in io_html, f"solver.io.{name} missing from the reference"
