"""Build the API reference (docs/api/) from the numpy-style docstrings.

    ./dev.sh docs            # writes docs/api/index.html (gitignored)
    ./dev.sh docs OUT_DIR    # elsewhere

It documents the public API only: ``solver`` (the names of its
``__all__``), ``solver.io`` and ``solver.examples``.  Any warning while
importing or rendering (a broken reference, a module that fails to import)
is an error, so the reference cannot rot; tests/test_api_docs.py runs the
same build.
"""

from __future__ import annotations

import os
import sys
import warnings
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
# the public modules; "!solver\..*" leaves out the internal sub-packages
SPECS = ("solver", "!solver\\..*", "solver.io", "solver.examples")


def build(out: Path) -> list[Path]:
    """Render the reference into ``out``; returns the HTML files written.

    Raises
    ------
    UserWarning (as an error)
        Whatever pdoc warns about.
    """
    os.environ.setdefault("PDOC_ALLOW_EXEC", "1")  # numpy/scipy probe the CPU at import
    sys.path.insert(0, str(ROOT))
    import pdoc
    import pdoc.render

    pdoc.render.configure(docformat="numpy", show_source=False, search=True,
                          footer_text="SymFrames API reference")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        pdoc.pdoc(*SPECS, output_directory=out)
    return sorted(out.rglob("*.html"))


def main(argv: list[str]) -> int:
    out = Path(argv[0]) if argv else ROOT / "docs" / "api"
    pages = build(out)
    print(f"wrote {len(pages)} pages: {out / 'index.html'}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
