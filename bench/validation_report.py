"""Validation report: every example domain, a refinement study, the paper's
targets (§5.2, §5.4).  See solver/validation_report.py for what is measured.

    python bench/validation_report.py            # full run (~20 min): writes bench/VALIDATION.md + plot
    python bench/validation_report.py --quick    # smoke run (a few minutes), prints only
    python bench/validation_report.py --help
"""

from __future__ import annotations

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from solver.validation_report import main  # noqa: E402

if __name__ == "__main__":
    sys.exit(main())
