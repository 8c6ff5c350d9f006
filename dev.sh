#!/usr/bin/env bash
# SymFrames developer entry point.  Creates .venv with the pinned
# requirements on first use (Python 3.11), then:
#   ./dev.sh demo [ARGS]   build the default example, compute it, write out/*.blend and a PNG
#   ./dev.sh test [ARGS]   lint (ruff), install CalculiX if missing (apt), then run the test suite on two
#                          processes (pytest ARGS; -n 0: one; -m "not slow": the ~1-minute fast loop)
#   ./dev.sh lint [ARGS]   ruff check (ARGS e.g. --fix)
#   ./dev.sh bench [ARGS]  run the benchmarks
#   ./dev.sh docs [DIR]    build the API reference (docs/api/index.html) from the docstrings
#   ./dev.sh matrix [ARGS] install and run the built extension in every supported Blender (bpy module) release
#   ./dev.sh python ...    run the venv's python
set -euo pipefail
ROOT="$(cd "$(dirname "$0")" && pwd)"
VENV="$ROOT/.venv"
PY="${PYTHON:-python3.11}"
command -v "$PY" >/dev/null 2>&1 || PY=python3
if [ ! -x "$VENV/bin/python" ] || ! cmp -s "$ROOT/requirements.txt" "$VENV/.requirements"; then
    echo "[dev.sh] creating $VENV with $("$PY" --version)" >&2
    "$PY" -m venv "$VENV"
    # uv (pinned) installs the same pinned wheels in half pip's time (15 s against 31 s here, its cache cold
    # and pip's warm); pip where uv cannot be had.  Byte-compiled at install, as pip does: uv does not by
    # default, and where PYTHONDONTWRITEBYTECODE is set every process (each test worker, each fTetWild child,
    # each CLI run) compiled scipy & co. again on import: 797 s of test work against 704 s
    if ! { "$VENV/bin/python" -m pip install --quiet uv==0.13.8 \
           && "$VENV/bin/uv" pip install --quiet --compile-bytecode --python "$VENV/bin/python" \
                  -r "$ROOT/requirements.txt"; }; then
        echo "[dev.sh] uv failed: installing with pip" >&2
        "$VENV/bin/python" -m pip install --quiet --upgrade pip
        "$VENV/bin/python" -m pip install --quiet -r "$ROOT/requirements.txt"
    fi
    cp "$ROOT/requirements.txt" "$VENV/.requirements"
fi
ensure_calculix() {  # tests/test_femformats.py runs CalculiX on the .inp files SymFrames writes
    command -v ccx >/dev/null 2>&1 && return 0
    local sudo=""
    [ "$(id -u)" = 0 ] || sudo="sudo"
    echo "[dev.sh] installing CalculiX (Debian's calculix-ccx) for the simulation-format tests" >&2
    { $sudo apt-get update -qq && { $sudo apt-get install -y -qq calculix-ccx=2.20-1 \
        || $sudo apt-get install -y -qq calculix-ccx; }; } >/dev/null \
        || { echo "[dev.sh] error: could not install calculix-ccx (apt-get install calculix-ccx, as root)" >&2; exit 1; }
}
cmd="${1:-help}"
shift || true
cd "$ROOT"
case "$cmd" in
    demo)   exec "$VENV/bin/python" scripts/symframes_run.py "$@" ;;
    test)   "$VENV/bin/ruff" check --quiet "$ROOT"
            ensure_calculix
            # one BLAS thread per worker: two workers on two cores, not four threads fighting (-15%); and one
            # sparse-product thread (solver/linalg/parallel.py): a 9k-tet solve took 30 s of CPU with one,
            # 40 s with two, in the same wall time, on a loaded machine.  Files are dealt whole, the heaviest
            # first (tests/conftest.py orders them by bench/SUITE.md), not xdist's most-tests-first
            OPENBLAS_NUM_THREADS="${OPENBLAS_NUM_THREADS:-1}" OMP_NUM_THREADS="${OMP_NUM_THREADS:-1}" \
                SYMFRAMES_THREADS="${SYMFRAMES_THREADS:-1}" \
                exec "$VENV/bin/python" -m pytest -q -n 2 --dist loadfile --no-loadscope-reorder "$@" ;;
    lint)   exec "$VENV/bin/ruff" check "$ROOT" "$@" ;;
    bench)  exec "$VENV/bin/python" bench/run_bench.py "$@" ;;
    docs)   exec "$VENV/bin/python" scripts/build_docs.py "$@" ;;
    matrix) exec "$VENV/bin/python" scripts/matrix.py "$@" ;;
    python) exec "$VENV/bin/python" "$@" ;;
    *) sed -n '2,11p' "$0"; exit 1 ;;
esac
