"""Replay many recordings: one `FileResult` per file, a summary table and a JSON report.

Each file goes through `edge.io.replay.replay_recording` (the single-file replay: recorded
profile, same pipeline, bit-for-bit comparison); `replay_one` only times it and turns every
failure into the result's ``error`` so one bad file never stops the others.  `replay_serial`
runs the files one after the other in this process; `edge.io.fleet.replay_on_ray` runs the
same `replay_one` as one Ray task per file.
"""

from __future__ import annotations

import glob
import os
import socket
import time
from dataclasses import asdict, dataclass
from typing import Any, Callable, Iterable, Sequence

__all__ = ["FileResult", "find_recordings", "replay_one", "replay_serial", "summary_lines", "report_dict"]


@dataclass
class FileResult:
    """What replaying one recording gave.  ``identical``: every recorded depth map (and confidence)
    was reproduced bit for bit and the file was whole; ``error``: why not, when it is not a mismatch."""

    path: str
    profile: str = ""
    stacks_read: int = 0
    stacks_compared: int = 0
    stacks_matched: int = 0
    stacks_differ: int = 0
    identical: bool = False
    decode_s: float = 0.0          # wall time of the replay (read + decode + compare), seconds
    error: str = ""
    first_mismatch: str = ""
    worker: str = ""               # host:pid that replayed it

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def find_recordings(specs: Iterable[str]) -> list[str]:
    """Expand files, directories (their ``*.mcap``, not recursive) and glob patterns into a sorted
    list of paths without duplicates (one file named twice, also as ``./a.mcap`` and ``a.mcap`` or
    through a link, is replayed once).  ValueError naming the spec that matched nothing."""
    out: list[str] = []
    seen: set[str] = set()
    for spec in specs:
        if os.path.isdir(spec):
            found = sorted(glob.glob(os.path.join(glob.escape(spec), "*.mcap")))
            if not found:
                raise ValueError(f"directory {spec!r} holds no *.mcap recording")
        elif os.path.exists(spec):
            found = [spec]
        elif glob.has_magic(spec):
            found = sorted(p for p in glob.glob(spec) if os.path.isfile(p))
            if not found:
                raise ValueError(f"pattern {spec!r} matches no file")
        else:
            raise ValueError(f"recording {spec!r} does not exist")
        for p in found:
            real = os.path.realpath(p)
            if real not in seen:
                seen.add(real)
                out.append(p)
    return out


def replay_one(path: str, expected_profile: Any = None) -> FileResult:
    """Replay one file (see module docstring); never raises for a bad file."""
    from .replay import replay_recording

    result = FileResult(path=os.fspath(path), worker=f"{socket.gethostname()}:{os.getpid()}")
    start = time.perf_counter()
    try:
        report = replay_recording(path, expected_profile=expected_profile)
    except Exception as exc:  # not a recording, no profile, unreadable: reported, not fatal
        result.error = f"{type(exc).__name__}: {exc}" if not _is_recording_error(exc) else str(exc)
        result.decode_s = time.perf_counter() - start
        return result
    result.decode_s = time.perf_counter() - start
    result.profile = report.profile
    result.stacks_read = report.stacks_read
    result.stacks_compared = report.stacks_compared
    result.stacks_matched = report.stacks_matched
    result.stacks_differ = len(report.mismatches)
    result.identical = report.ok
    result.first_mismatch = report.mismatches[0] if report.mismatches else ""
    if report.problem:
        result.error = report.problem
    elif report.stacks_compared == 0:
        result.error = "no recorded depth output to compare against"
    return result


def _is_recording_error(exc: BaseException) -> bool:
    from edge.io.mcap import RecordingError

    return isinstance(exc, RecordingError)


def replay_serial(paths: Sequence[str], expected_profile: Any = None,
                  on_done: Callable[[FileResult], None] | None = None) -> list[FileResult]:
    """`replay_one` for each path in turn, in this process (no Ray needed)."""
    results = []
    for path in paths:
        results.append(replay_one(path, expected_profile))
        if on_done is not None:
            on_done(results[-1])
    return results


def summary_lines(results: Sequence[FileResult], *, wall_s: float, workers: int, engine: str) -> list[str]:
    """The summary table: one row per file, then the totals."""
    names = [os.path.basename(r.path) for r in results]
    if len(set(names)) < len(names):  # two files of one name in different folders: tell them apart
        names = [os.path.relpath(r.path) for r in results]
    width = max([len("file")] + [len(n) for n in names])
    head = f"{'file':<{width}}  {'profile':<12}  stacks  identical  decode s  error"
    lines = [head, "-" * len(head)]
    for name, r in zip(names, results):
        stacks = f"{r.stacks_matched}/{r.stacks_compared}"
        err = (r.error or r.first_mismatch).replace("\n", " ")
        lines.append(f"{name:<{width}}  {r.profile or '-':<12}  {stacks:>6}  {'yes' if r.identical else 'NO':<9}  "
                     f"{r.decode_s:8.2f}  {err[:100]}")
    n_ok = sum(r.identical for r in results)
    n_diff = sum(r.stacks_differ > 0 for r in results)
    n_err = sum(bool(r.error) and r.stacks_differ == 0 for r in results)
    lines.append(f"{len(results)} recordings: {n_ok} bit-identical, {n_diff} differ, {n_err} failed; "
                 f"{sum(r.stacks_compared for r in results)} depth maps compared; "
                 f"{wall_s:.2f} s wall on {engine} ({workers} worker{'s' if workers != 1 else ''})")
    return lines


def report_dict(results: Sequence[FileResult], *, wall_s: float, workers: int, engine: str,
                address: str | None = None) -> dict[str, Any]:
    """The JSON report (``all_identical`` is what the exit code says)."""
    return {
        "version": 1,
        "engine": engine,
        "workers": workers,
        "address": address,
        "wall_s": round(wall_s, 3),
        "recordings": len(results),
        "identical": sum(r.identical for r in results),
        "all_identical": bool(results) and all(r.identical for r in results),
        "files": [r.as_dict() for r in results],
    }
