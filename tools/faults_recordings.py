"""Fault suite: corrupt recordings through `edge replay`, `edge replay --recover` and `edge run --sensor replay`.

Mutants are made from the committed tests/data/sim-small.mcap (3 stacks of the test-small profile),
re-chunked into 64 KiB chunks, zstd-compressed and uncompressed, so a damaged chunk is one of ~20:

  truncate      cut at a random offset
  flip-zstd     one byte flipped inside a zstd-compressed chunk's data
  flip-raw      one byte flipped inside an uncompressed chunk's data
  flip-header   one byte flipped in a chunk's record header (opcode / length / chunk fields)
  zero          a random region (16 B - 4 KiB) zeroed
  cut-tail      the last 1..37 bytes cut (closing magic, footer)
  flip-summary  one byte flipped in the summary section (chunk indexes, statistics, ...)
  append        1..4096 random bytes appended
  flip-profile  one byte flipped inside the recorded profile's JSON metadata
  flip-any      one byte flipped anywhere

Each mutant is run in-process through `edge.cli.main` (stdout/stderr captured) and classified:
``ok`` (exit 0, and the independent mcap library accepts the file), ``clean`` (exit 2 with one
``error:`` line on stderr), ``traceback`` (an exception escaped), ``hang`` (over the time limit),
``unclear`` (any other exit / several error lines) and ``silent-wrong`` (exit 0 or "bit for bit"
on a file the mcap library rejects; for --recover: "the input was complete" on a damaged input).
For --recover the frames salvaged are counted against the frames in the chunks the mutation left
intact (what the file still held).

    python tools/faults_recordings.py           # CI-sized sample (about 40 mutants)
    python tools/faults_recordings.py --full    # >= 100 mutants x 3 commands
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import struct
import sys
import tempfile
import time
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

SOURCE = ROOT / "tests" / "data" / "sim-small.mcap"
MAGIC = b"\x89MCAP0\r\n"
KINDS = ("truncate", "flip-zstd", "flip-raw", "flip-header", "zero", "cut-tail", "flip-summary", "append",
         "flip-profile", "flip-any")
HANG_S = 60.0


# -- base recordings ------------------------------------------------------------------------------

def rechunk(src: Path, dst: Path, *, chunk_size: int, compression: str) -> None:
    """Rewrite ``src`` record by record (file order) into ``dst`` with other chunks (mcap's own API)."""
    from mcap.records import Attachment, Channel, Header, Message, Metadata, Schema
    from mcap.stream_reader import StreamReader
    from mcap.writer import CompressionType, Writer

    comp = {"zstd": CompressionType.ZSTD, "none": CompressionType.NONE}[compression]
    with open(src, "rb") as f, open(dst, "wb") as out:
        w = Writer(out, chunk_size=chunk_size, compression=comp, enable_crcs=True, enable_data_crcs=True)
        schemas: dict[int, int] = {}
        channels: dict[int, int] = {}
        for r in StreamReader(f, validate_crcs=True).records:
            if isinstance(r, Header):
                w.start(profile=r.profile, library=r.library)
            elif isinstance(r, Schema) and r.id not in schemas:
                schemas[r.id] = w.register_schema(r.name, r.encoding, r.data)
            elif isinstance(r, Channel) and r.id not in channels:
                channels[r.id] = w.register_channel(r.topic, r.message_encoding, schemas.get(r.schema_id, 0),
                                                    dict(r.metadata))
            elif isinstance(r, Message):
                w.add_message(channels[r.channel_id], r.log_time, r.data, r.publish_time, r.sequence)
            elif isinstance(r, Metadata):
                w.add_metadata(r.name, dict(r.metadata))
            elif isinstance(r, Attachment):
                w.add_attachment(r.create_time, r.log_time, r.name, r.media_type, r.data)
        w.finish()


@dataclass
class Layout:
    """Where things are in a base recording (from its own summary) and raw frames per chunk."""

    data: bytes
    chunks: list[tuple[int, int]]             # (start, length) of every chunk record
    frames_in_chunk: list[int]
    summary_start: int
    footer: int
    profile_json: tuple[int, int]             # byte range of the edge.profile JSON text
    frames: int = 0


def layout(path: Path) -> Layout:
    from mcap.reader import make_reader
    from mcap.records import Chunk, Message
    from mcap.stream_reader import StreamReader, breakup_chunk

    data = path.read_bytes()
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    chunks = sorted((c.chunk_start_offset, c.chunk_length) for c in summary.chunk_indexes)
    raw_ids = {cid for cid, c in summary.channels.items() if c.topic.endswith("/raw")}
    per_chunk = []
    with open(path, "rb") as f:
        for r in StreamReader(f, emit_chunks=True).records:
            if isinstance(r, Chunk):
                per_chunk.append(sum(1 for m in breakup_chunk(r) if isinstance(m, Message) and m.channel_id in raw_ids))
    footer_pos = len(data) - len(MAGIC) - 29
    summary_start = struct.unpack_from("<Q", data, footer_pos + 9)[0]
    start = data.find(b'{"camera"')          # the canonical profile JSON (sorted keys) in edge.profile
    end = data.find(b"}}", start) + 2
    return Layout(data, chunks, per_chunk, summary_start, footer_pos, (start, end), sum(per_chunk))


def bases(workdir: Path) -> dict[str, Layout]:
    out = {}
    for name, comp in (("zstd", "zstd"), ("raw", "none")):
        p = workdir / f"base-{name}.mcap"
        rechunk(SOURCE, p, chunk_size=64 * 1024, compression=comp)
        out[name] = layout(p)
    return out


# -- mutants ---------------------------------------------------------------------------------------

@dataclass
class Mutant:
    kind: str
    base: str
    data: bytes
    touched: tuple[int, int]   # byte range changed (end exclusive); truncation: (cut, inf)
    note: str = ""

    def intact_frames(self, lay: Layout) -> int:
        """Raw frames in chunks the mutation did not touch (what the file still holds)."""
        a, b = self.touched
        return sum(n for (s, ln), n in zip(lay.chunks, lay.frames_in_chunk) if s + ln <= a or s >= b)


def _flip(data: bytes, pos: int, rng: np.random.Generator) -> bytes:
    b = bytearray(data)
    b[pos] ^= int(rng.integers(1, 256))
    return bytes(b)


def make_mutant(kind: str, lays: dict[str, Layout], rng: np.random.Generator) -> Mutant:
    base = "raw" if kind == "flip-raw" else ("zstd" if kind in ("flip-zstd",) else str(rng.choice(["zstd", "raw"])))
    lay = lays[base]
    data, n = lay.data, len(lay.data)
    if kind == "truncate":
        cut = int(rng.integers(8, n - 1))
        return Mutant(kind, base, data[:cut], (cut, 1 << 62), f"cut at {cut} of {n}")
    if kind in ("flip-zstd", "flip-raw"):
        s, ln = lay.chunks[int(rng.integers(len(lay.chunks)))]
        head = 9 + 8 + 8 + 8 + 4 + 4 + (4 if base == "zstd" else 0) + 8   # chunk fields before its data
        pos = int(rng.integers(s + head, s + ln))
        return Mutant(kind, base, _flip(data, pos, rng), (pos, pos + 1), f"byte {pos}")
    if kind == "flip-header":
        s, _ = lay.chunks[int(rng.integers(len(lay.chunks)))]
        pos = s + int(rng.integers(0, 9 + 36))
        return Mutant(kind, base, _flip(data, pos, rng), (pos, pos + 1), f"byte {pos}")
    if kind == "zero":
        ln = int(rng.integers(16, 4097))
        pos = int(rng.integers(8, n - ln))
        b = bytearray(data)
        b[pos:pos + ln] = bytes(ln)
        return Mutant(kind, base, bytes(b), (pos, pos + ln), f"{ln} bytes at {pos}")
    if kind == "cut-tail":
        k = int(rng.integers(1, len(MAGIC) + 30))
        return Mutant(kind, base, data[:n - k], (n - k, 1 << 62), f"last {k} bytes")
    if kind == "flip-summary":
        pos = int(rng.integers(lay.summary_start, lay.footer))
        return Mutant(kind, base, _flip(data, pos, rng), (pos, pos + 1), f"byte {pos}")
    if kind == "append":
        k = int(rng.integers(1, 4097))
        return Mutant(kind, base, data + rng.integers(0, 256, k, dtype=np.uint8).tobytes(), (n, n + k),
                      f"{k} bytes")
    if kind == "flip-profile":
        a, b = lay.profile_json
        pos = int(rng.integers(a, b))
        return Mutant(kind, base, _flip(data, pos, rng), (pos, pos + 1), f"byte {pos}")
    if kind == "flip-any":
        pos = int(rng.integers(0, n))
        return Mutant(kind, base, _flip(data, pos, rng), (pos, pos + 1), f"byte {pos}")
    raise ValueError(f"unknown mutation kind {kind!r}")


# -- the independent check -------------------------------------------------------------------------

def library_accepts(path: Path) -> bool:
    """True if the mcap library (stream pass with CRCs, then the indexed reader) and a plain zlib
    check of the footer's summary CRC all accept the file."""
    from mcap.reader import make_reader
    from mcap.records import Footer
    from mcap.stream_reader import StreamReader

    data = path.read_bytes()
    try:
        with open(path, "rb") as f:
            footer = None
            for r in StreamReader(f, validate_crcs=True, record_size_limit=len(data)).records:
                if isinstance(r, Footer):
                    footer = r
            if footer is None or f.read(1):
                return False
        with open(path, "rb") as f:
            reader = make_reader(f, validate_crcs=True)
            summary = reader.get_summary()
            if summary is None or sum(1 for _ in reader.iter_messages()) != summary.statistics.message_count:
                return False
        fpos = len(data) - len(MAGIC) - 29
        if footer.summary_crc and zlib.crc32(data[footer.summary_start or fpos:fpos + 9 + 16]) != footer.summary_crc:
            return False
    except Exception:
        return False
    return True


# -- running the CLI -------------------------------------------------------------------------------

@dataclass
class Run:
    outcome: str              # ok | clean | traceback | hang | unclear | silent-wrong
    rc: int | None
    stderr: str
    stdout: str
    seconds: float
    salvaged: int | None = None


def cli(argv: list[str]) -> tuple[int | None, str, str, str | None, float]:
    """Run ``edge ARGV`` in this process: (exit code, stdout, stderr, escaped exception, seconds)."""
    from edge.cli import main

    out, err = io.StringIO(), io.StringIO()
    t0 = time.monotonic()
    exc = None
    rc: int | None = None
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            rc = main(argv)
        except SystemExit as e:
            rc = e.code if isinstance(e.code, int) else 2
        except BaseException as e:  # noqa: BLE001 - this is what the suite looks for
            exc = f"{type(e).__name__}: {e}"
    return rc, out.getvalue(), err.getvalue(), exc, time.monotonic() - t0


def classify(rc: int | None, stdout: str, stderr: str, exc: str | None, seconds: float, *,
             accepted: bool, recover: bool) -> str:
    if exc is not None or "Traceback" in stderr:
        return "traceback"
    if seconds > HANG_S:
        return "hang"
    if rc == 0:
        if recover:
            return "silent-wrong" if (not accepted and "the input was complete" in stdout) else "ok"
        return "ok" if accepted else "silent-wrong"
    if not accepted and "bit for bit" in stdout:
        return "silent-wrong"
    lines = [ln for ln in stderr.splitlines() if ln.strip()]
    if rc == 2 and len(lines) == 1 and "error:" in lines[0]:
        return "clean"
    return "unclear"


def run_mutant(m: Mutant, lays: dict[str, Layout], workdir: Path, idx: int, *, sensor: bool) -> dict[str, Run]:
    path = workdir / f"m{idx:04d}-{m.kind}.mcap"
    path.write_bytes(m.data)
    accepted = library_accepts(path)
    runs: dict[str, Run] = {}
    rc, so, se, exc, s = cli(["replay", str(path)])
    runs["replay"] = Run(classify(rc, so, se, exc, s, accepted=accepted, recover=False), rc, se, so, s)
    out = workdir / f"m{idx:04d}.recovered.mcap"
    rc, so, se, exc, s = cli(["replay", "--recover", "--out", str(out), str(path)])
    r = Run(classify(rc, so, se, exc, s, accepted=accepted, recover=True), rc, se, so, s)
    if out.exists() and exc is None:
        r.salvaged = _raw_frames(out)
        if r.outcome == "ok" and not library_accepts(out):
            r.outcome = "silent-wrong"  # --recover wrote a file the library rejects
    runs["recover"] = r
    if sensor:
        rc, so, se, exc, s = cli(["run", "--sensor", "replay", "--replay", str(path), "--no-zenoh", "--max-speed",
                                  "--quiet", "--profile", str(ROOT / "tests" / "data" / "profiles" / "test-small.toml")])
        runs["sensor"] = Run(classify(rc, so, se, exc, s, accepted=accepted, recover=False), rc, se, so, s)
    for p in (path, out):
        with contextlib.suppress(FileNotFoundError):
            p.unlink()
    return runs


def _raw_frames(path: Path) -> int:
    """Raw camera frames in a (recovered) file, counted with the mcap library."""
    from mcap.reader import make_reader

    try:
        with open(path, "rb") as f:
            return sum(1 for _, ch, _ in make_reader(f, validate_crcs=True).iter_messages()
                       if ch.topic.endswith("/raw"))
    except Exception:
        return 0


# -- the suite --------------------------------------------------------------------------------------

@dataclass
class KindResult:
    kind: str
    trials: int = 0
    outcomes: dict[str, dict[str, int]] = field(default_factory=dict)   # command -> outcome -> count
    salvaged: int = 0
    intact: int = 0
    held_short: int = 0     # recover runs that salvaged fewer frames than the intact chunks held
    examples: list[str] = field(default_factory=list)

    def add(self, runs: dict[str, Run], m: Mutant, lay: Layout) -> None:
        self.trials += 1
        for cmd, r in runs.items():
            self.outcomes.setdefault(cmd, {}).setdefault(r.outcome, 0)
            self.outcomes[cmd][r.outcome] += 1
            if r.outcome not in ("ok", "clean") and len(self.examples) < 3:
                self.examples.append(f"{cmd} {m.kind} ({m.base}, {m.note}): {r.outcome} rc={r.rc} "
                                     f"{(r.stderr.strip().splitlines() or [''])[-1][:200]}")
        rec = runs["recover"]
        held = m.intact_frames(lay)
        self.intact += held
        self.salvaged += rec.salvaged or 0
        if (rec.salvaged or 0) < held:
            self.held_short += 1
            if len(self.examples) < 3:
                self.examples.append(f"recover {m.kind} ({m.base}, {m.note}): salvaged {rec.salvaged} "
                                     f"of {held} intact frames")

    @property
    def bad(self) -> int:
        return sum(n for o in self.outcomes.values() for k, n in o.items() if k not in ("ok", "clean"))


def run_suite(*, per_kind: int, sensor_every: int, seed: int = 12,
              progress: Callable[[str], None] | None = None) -> list[KindResult]:
    """``per_kind`` mutants of every kind; `edge run --sensor replay` on every ``sensor_every``-th."""
    rng = np.random.default_rng(seed)
    results = []
    with tempfile.TemporaryDirectory(prefix="edge-faults-") as tmp:
        work = Path(tmp)
        lays = bases(work)
        cli(["replay", str(work / "base-zstd.mcap")])  # compile the decoder first: not a hang
        idx = 0
        for kind in KINDS:
            res = KindResult(kind)
            for _ in range(per_kind):
                m = make_mutant(kind, lays, rng)
                while m.data == lays[m.base].data:
                    m = make_mutant(kind, lays, rng)
                runs = run_mutant(m, lays, work, idx, sensor=idx % sensor_every == 0)
                res.add(runs, m, lays[m.base])
                idx += 1
            results.append(res)
            if progress is not None:
                progress(f"{kind}: {res.trials} mutants, {res.bad} bad outcomes")
    return results


def _outcome_text(r: KindResult) -> str:
    parts = []
    for cmd in ("replay", "recover", "sensor"):
        o = r.outcomes.get(cmd)
        if o:
            parts.append(f"{cmd}: " + ", ".join(f"{n} {k}" for k, n in sorted(o.items())))
    parts.append(f"frames salvaged {r.salvaged} of {r.intact} intact")
    return "; ".join(parts)


def _rows(results: list[KindResult]) -> list[dict[str, Any]]:
    return [{"fault": f"corrupt recording: {r.kind}", "trials": r.trials, "outcomes": _outcome_text(r),
             "target": "0 tracebacks, 0 hangs, 0 silent wrong results; --recover salvages every intact chunk",
             "met": r.bad == 0 and r.held_short == 0} for r in results]


def rows(full: bool) -> list[dict[str, Any]]:
    """One row per mutation kind (fault, trials, outcomes, target, met) for tools/fault_report.py:
    12 mutants per kind (120) with --sensor replay on every second one when ``full``, else 4 per kind."""
    os.environ.setdefault("NUMBA_CACHE_DIR", str(ROOT / ".numba_cache"))
    return _rows(run_suite(per_kind=12 if full else 4, sensor_every=2 if full else 5))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--full", action="store_true", help="120 mutants x (replay, --recover) + 60 x --sensor replay")
    args = ap.parse_args()
    t0 = time.monotonic()
    os.environ.setdefault("NUMBA_CACHE_DIR", str(ROOT / ".numba_cache"))
    results = run_suite(per_kind=12 if args.full else 4, sensor_every=2 if args.full else 5)
    table = _rows(results)
    print("| fault | trials | outcomes | target | met |\n|---|---|---|---|---|")
    for r in table:
        print(f"| {r['fault']} | {r['trials']} | {r['outcomes']} | {r['target']} | {'yes' if r['met'] else 'NO'} |")
    for r in results:
        for e in r.examples:
            print(f"  {e}")
    print(f"{sum(r['trials'] for r in table)} mutants in {time.monotonic() - t0:.0f} s")
    return 0 if all(r["met"] for r in table) else 1


if __name__ == "__main__":
    from edge.cli import tool_main

    raise SystemExit(tool_main(main, __file__))
