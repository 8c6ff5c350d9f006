"""The test suite's time per file: where the minutes of ``./dev.sh test`` go.

    python bench/suite_durations.py                 # run the suite as CI does, print the table
    python bench/suite_durations.py --write         # also (re)write bench/SUITE.md
    python bench/suite_durations.py --from out.txt  # a saved ``pytest --durations=0`` output

It runs ``pytest -n 2 --dist loadfile --no-loadscope-reorder --durations=0``
(the heaviest files first: tests/conftest.py orders them by this table) with one BLAS thread
and one sparse-product thread per worker (what ``./dev.sh test`` runs) and
adds up each file's setup, call and teardown seconds.  The sum of a file's
seconds is the work it costs; on two workers the wall time is about
half the total, as files are dealt to the two processes whole.  A session
fixture's seconds (a shared solve, a meshed example) count for the first
file that asks for it.
"""

from __future__ import annotations

import argparse
import os
import platform
import re
import subprocess
import sys
import time
from collections import defaultdict

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
LINE = re.compile(r"^\s*([\d.]+)s (setup|call|teardown)\s+(tests/[^:]+\.py)::")
SUMMARY = re.compile(r"(\d+) passed.* in ([\d.]+)s")


def per_file(text: str) -> dict[str, float]:
    """Seconds per test file from ``pytest --durations=0`` output."""
    out: dict[str, float] = defaultdict(float)
    for line in text.splitlines():
        m = LINE.match(line)
        if m:
            out[m.group(3)] += float(m.group(1))
    return dict(out)


def table(files: dict[str, float], wall: float | None, passed: int | None) -> str:
    total = sum(files.values())
    rows = sorted(files.items(), key=lambda kv: -kv[1])
    lines = ["| test file | seconds | share |", "|---|---:|---:|"]
    lines += [f"| `{f}` | {s:.1f} | {100 * s / total:.1f}% |" for f, s in rows]
    head = [f"{len(files)} files, {total:.0f} s of test work"]
    if wall is not None:
        head.append(f"{wall:.0f} s wall on 2 workers" + (f", {passed:,} tests passed" if passed else ""))
    return "; ".join(head) + ".\n\n" + "\n".join(lines) + "\n"


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--from", dest="source", help="a saved pytest --durations=0 output instead of running")
    p.add_argument("--write", action="store_true", help="write bench/SUITE.md")
    p.add_argument("pytest_args", nargs="*", help="extra pytest arguments (e.g. -m 'not slow')")
    args = p.parse_args(argv)
    wall = passed = None
    if args.source:
        text = open(args.source).read()
    else:
        t = time.perf_counter()
        cmd = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-n", "2", "--dist", "loadfile",
               "--no-loadscope-reorder", "--durations=0", "tests", *args.pytest_args]
        # as ./dev.sh test: one BLAS and one sparse-product thread per worker
        env = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "SYMFRAMES_THREADS": "1", **os.environ}
        run = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, env=env)
        text, wall = run.stdout, time.perf_counter() - t
        if run.returncode != 0:
            # a failed or erroring test: its name and the summary, nothing recorded
            tail = [line for line in text.splitlines() if line.startswith(("FAILED", "ERROR"))]
            print("\n".join(tail + text.strip().splitlines()[-1:]) or run.stderr[-2000:], file=sys.stderr)
            print(f"pytest exited with {run.returncode}: the table is not recorded", file=sys.stderr)
            return 1
    m = SUMMARY.search(text)
    if m:
        passed = int(m.group(1))
        wall = wall if wall is not None else float(m.group(2))
    files = per_file(text)
    if not files:
        print("no durations found (was pytest run with --durations=0?)", file=sys.stderr)
        return 1
    body = table(files, wall, passed)
    print(body)
    if args.write:
        with open(os.path.join(ROOT, "bench", "SUITE.md"), "w") as fh:
            fh.write("# The test suite's time per file\n\n"
                     f"`python bench/suite_durations.py --write` on {platform.machine()} ({_cpu()}), "
                     f"{os.cpu_count()} cores, `pytest -n 2 --dist loadfile --no-loadscope-reorder` "
                     "(the heaviest files first) as `./dev.sh test` runs it. "
                     "A file's seconds add up its tests' setup, call and teardown; a shared session "
                     "fixture counts for the first file that asks for it.\n\n" + body)
    return 0


def _cpu() -> str:
    """The processor's model name (the suite's seconds vary with it: the
    same commit took 400 s and 300 s of wall time on two 2-core machines)."""
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "processor unknown"


if __name__ == "__main__":
    sys.exit(main())
