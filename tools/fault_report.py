"""The fault table of the README ("Faults and deployment"): fault | trials | outcomes | target | met.

Rows come from tools/faults_lifecycle.py (signals over the service's life, SIGKILL salvage, a full
disk, start-up errors) and, when they exist, from tools/faults_recordings.py (corrupted
recordings) and tools/faults_fuzz.py (property-based fuzzing); each exposes ``rows(full) ->
list[dict]`` with the keys of the table.

    python tools/fault_report.py            # the CI-sized trials (about a minute or two)
    python tools/fault_report.py --full     # >= 20 signal points, warm and cold numba cache
    python tools/fault_report.py --full --markdown   # the README table

Exit code 1 when a target is not met.
"""

from __future__ import annotations

import argparse
import importlib
import os
import platform
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

COLUMNS = ("fault", "trials", "outcomes", "target", "met")
SOURCES = ("faults_lifecycle", "faults_recordings", "faults_fuzz")


def machine() -> str:
    cpus = os.cpu_count() or 0
    mem = ""
    try:
        with open("/proc/meminfo") as f:
            kb = int(f.readline().split()[1])
        mem = f", {kb / 2**20:.0f} GiB RAM"
    except (OSError, ValueError, IndexError):
        pass
    try:
        load = f", load average {os.getloadavg()[0]:.1f}"
    except OSError:
        load = ""
    return f"{platform.machine()} {platform.system()} {platform.release()}, {cpus} CPUs{mem}{load}, Python {platform.python_version()}"


def collect(full: bool) -> tuple[list[dict], list[str]]:
    rows, notes = [], []
    for name in SOURCES:
        try:
            module = importlib.import_module(name)
        except ModuleNotFoundError as exc:
            if exc.name == name:
                notes.append(f"{name}.py not present: its rows are missing")
                continue
            raise
        t0 = time.monotonic()
        got = module.rows(full)
        notes.append(f"{name}: {len(got)} rows in {time.monotonic() - t0:.0f} s")
        rows += got
    return rows, notes


def render(rows: list[dict], markdown: bool) -> str:
    cells = [[str(r.get(c, "")) if c != "met" else ("yes" if r.get("met") else "NO") for c in COLUMNS] for r in rows]
    if markdown:
        out = ["| " + " | ".join(COLUMNS) + " |", "|" + "---|" * len(COLUMNS)]
        out += ["| " + " | ".join(c.replace("|", "/") for c in row) + " |" for row in cells]
        return "\n".join(out)
    widths = [max(len(c), *(len(row[i]) for row in cells)) if cells else len(c) for i, c in enumerate(COLUMNS)]
    line = lambda row: " | ".join(x.ljust(w) for x, w in zip(row, widths))  # noqa: E731
    return "\n".join([line(list(COLUMNS)), "-+-".join("-" * w for w in widths), *map(line, cells)])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="Run the fault trials and print one table (fault | trials | "
                                             "outcomes | target | met).")
    ap.add_argument("--full", action="store_true",
                    help="the long version: >= 20 signal points with warm and cold numba cache, and the full "
                         "recording / fuzz trials of the other row sources")
    ap.add_argument("--markdown", action="store_true", help="print the table as markdown (for the README)")
    args = ap.parse_args(argv)
    t0 = time.monotonic()
    rows, notes = collect(args.full)
    print(render(rows, args.markdown))
    print()
    print(f"machine: {machine()}")
    print(f"command: python tools/fault_report.py{' --full' if args.full else ''}{' --markdown' if args.markdown else ''}"
          f" ({time.monotonic() - t0:.0f} s)")
    for n in notes:
        print(f"note: {n}")
    return 0 if rows and all(r.get("met") for r in rows) else 1


if __name__ == "__main__":
    from edge.cli import tool_main

    raise SystemExit(tool_main(main, __file__))
