"""Fault suite: property-based fuzzing (hypothesis) of profiles, config updates over zenoh, and decode().

Three properties, each run with a small example budget in CI and a large one here (``--full``):

  profiles   TOML text (the test profile with keys set to values of any type, new keys, deleted
             keys, random text and bytes) through `load_profile` and `edge profiles check`: a
             `Profile` that round-trips, or one `ProfileError` line naming the file; nothing else.
  config     updates to a live service's ``sl/<device>/config`` queryable over a real zenoh session
             on loopback: JSON objects of any shape, ``?key=value`` parameters, megabyte payloads,
             wrong types, out-of-range values: an accepted profile equal to the running one, or one
             ``config update rejected: ...`` line (at most MAX_REASON_CHARS + a prefix), the running
             config unchanged and ``config_rejected`` one higher; never no reply.
  decode     `edge.decode.decode` with any shapes, dtypes, NaN / inf, empty, mismatched, 1-pixel
             images and any keyword values: a `Decoded` of the right shapes, or one ValueError line.
             ``--full`` adds a 4000 x 3000 stack (hard decoder) with its traced memory bounded.

The budget is chosen by ``EDGE_FUZZ`` (``ci``, the default, or ``full``); ``rows(full)`` sets it.

    python tools/faults_fuzz.py           # CI budget
    python tools/faults_fuzz.py --full    # thousands of examples + the 4000 x 3000 stack
    python tools/faults_fuzz.py --full --seed 7 --examples 5000   # another draw, a bigger budget
"""

from __future__ import annotations

import argparse
import contextlib
import copy
import io
import json
import math
import os
import socket
import sys
import tempfile
import time
import traceback
import tracemalloc
from collections import Counter
from pathlib import Path
from typing import Any, Callable

import numpy as np
from hypothesis import HealthCheck, given, seed, settings
from hypothesis import strategies as st

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))
TEST_PROFILE = ROOT / "tests" / "data" / "profiles" / "test-small.toml"

#: examples per property (ci / full)
BUDGETS = {"ci": {"profiles": 60, "config": 40, "decode": 60},
           "full": {"profiles": 2000, "config": 500, "decode": 1500}}
#: CI's small budget is derandomised: a fixed example sequence, so a run cannot go red by the luck
#: of the draw (60 random decode() inputs hold only about three decodable ones); the full mode
#: explores at random.
for _name, _b in BUDGETS.items():
    settings.register_profile(f"edge-{_name}", deadline=None, database=None, print_blob=True,
                              suppress_health_check=list(HealthCheck), derandomize=_name == "ci")


#: ``--seed`` / ``--examples``: hypothesis' random seed and the examples per property (None: the
#: budget's own); a seed makes a full run repeatable (the CI budget is derandomised anyway)
RUN: dict[str, int | None] = {"seed": None, "examples": None}


def budget(kind: str) -> int:
    return RUN["examples"] or BUDGETS[os.environ.get("EDGE_FUZZ", "ci")][kind]


def _settings(kind: str) -> Callable[[Callable[..., None]], Callable[..., None]]:
    """The decorator for property `kind`: its budget's settings, and ``RUN["seed"]`` when set."""
    chosen = settings(settings.get_profile(f"edge-{os.environ.get('EDGE_FUZZ', 'ci')}"),
                      max_examples=budget(kind))

    def apply(prop: Callable[..., None]) -> Callable[..., None]:
        prop = chosen(prop)
        return prop if RUN["seed"] is None else seed(RUN["seed"])(prop)

    return apply


def _one_line(text: str) -> bool:
    return bool(text) and "\n" not in text and "Traceback" not in text


class Crash(AssertionError):
    """A property failed: not an accepted value and not one clear rejection."""


# -- TOML -----------------------------------------------------------------------------------------

def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return "nan" if math.isnan(v) else ("inf" if v > 0 else "-inf") if math.isinf(v) else repr(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{json.dumps(str(k))} = {_toml_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(type(v))


def to_toml(d: dict[str, Any]) -> str:
    """A nested dict as TOML (top-level scalars first, then one [table] per dict)."""
    lines = [f"{json.dumps(k)} = {_toml_value(v)}" for k, v in d.items() if not isinstance(v, dict)]
    for k, v in d.items():
        if isinstance(v, dict):
            lines.append(f"[{json.dumps(k)}]")
            lines += [f"{json.dumps(kk)} = {_toml_value(vv)}" for kk, vv in v.items()]
    return "\n".join(lines) + "\n"


def _base_profile() -> dict[str, Any]:
    from edge.profiles import load_profile, profile_to_dict

    return profile_to_dict(load_profile(TEST_PROFILE))


def _dotted(d: dict[str, Any]) -> list[str]:
    out = []
    for k, v in d.items():
        out += [f"{k}.{kk}" for kk in v] if isinstance(v, dict) else [k]
    return out


SCALARS = st.one_of(st.none(), st.booleans(), st.integers(-(2**70), 2**70), st.integers(-5, 300),
                    st.floats(allow_nan=True, allow_infinity=True), st.floats(-1e3, 1e3),
                    st.text(max_size=30), st.sampled_from(["soft", "hard", "list+median", "curtain", "zstd", "",
                                                           "tcp/127.0.0.1:0", "1101", "peer", "sim"]))
VALUES = st.one_of(SCALARS, st.lists(st.one_of(st.text(max_size=12), st.integers()), max_size=3),
                   st.dictionaries(st.text(max_size=6), st.integers(), max_size=2))


@st.composite
def profile_documents(draw) -> bytes:
    """TOML bytes: the test profile mutated, or arbitrary text / bytes."""
    kind = draw(st.sampled_from(["mutated"] * 6 + ["text", "bytes", "flipped"]))
    if kind == "text":
        return draw(st.text(max_size=300)).encode("utf-8", "surrogatepass")
    if kind == "bytes":
        return draw(st.binary(max_size=300))
    base = _base_profile()
    if kind == "flipped":
        raw = bytearray(to_toml(base).encode())
        for _ in range(draw(st.integers(1, 3))):
            raw[draw(st.integers(0, len(raw) - 1))] = draw(st.integers(0, 255))
        return bytes(raw)
    doc = copy.deepcopy(base)
    keys = _dotted(base) + ["extra", "camera.extra", "nope.key", "zenoh.access_control", "zenoh.config_writes"]
    for key, value in draw(st.lists(st.tuples(st.sampled_from(keys), VALUES), min_size=1, max_size=4)):
        table, _, leaf = key.partition(".")
        node = doc if not leaf else doc.setdefault(table, {})
        if not isinstance(node, dict):
            continue
        name = leaf or table
        if value is None:
            node.pop(name, None)
        else:
            node[name] = value
    try:
        return to_toml(doc).encode("utf-8", "surrogatepass")
    except TypeError:
        return b"name = 1\n"


def check_profile_document(data: bytes, workdir: Path, tally: Counter) -> None:
    from edge.cli import main
    from edge.profiles import ProfileError, load_profile, profile_from_dict, profile_to_dict

    path = workdir / "fuzz.toml"
    path.write_bytes(data)
    try:
        p = load_profile(path)
    except ProfileError as exc:
        if not (_one_line(str(exc)) and str(exc).startswith(str(path))):
            raise Crash(f"rejection not one line naming the file: {str(exc)[:300]!r}") from None
        tally["rejected"] += 1
    except Exception as exc:
        raise Crash(f"load_profile crashed: {type(exc).__name__}: {str(exc)[:300]}") from exc
    else:
        again = profile_from_dict(profile_to_dict(p), source=str(path))
        if again != p:
            raise Crash("accepted profile does not round-trip through profile_to_dict")
        tally["accepted"] += 1
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        rc = main(["profiles", "check", str(path)])
    lines = out.getvalue().splitlines()
    if rc not in (0, 1) or len(lines) != 1 or not (lines[0].startswith("ok: ") or lines[0].startswith(f"error: {path}")):
        raise Crash(f"edge profiles check: rc={rc}, output {out.getvalue()[:300]!r}")


def fuzz_profiles(tally: Counter) -> None:
    with tempfile.TemporaryDirectory(prefix="edge-fuzz-") as tmp:
        @_settings("profiles")
        @given(profile_documents())
        def prop(data: bytes) -> None:
            check_profile_document(data, Path(tmp), tally)

        prop()


# -- config updates over zenoh ---------------------------------------------------------------------

TABLES = ["decoder", "edc", "geometry", "camera", "zenoh", "name", "code", "sim", "projector"]
LEAVES = ["method", "min_contrast", "min_confidence", "min_disparity", "max_disparity", "rounds", "baseline_m",
          "focal_px", "cx_camera", "cx_projector", "cy", "width", "status_period_s", "bogus"]
SAFE = "abcdefghijklmnopqrstuvwxyz0123456789._-+[]{}\",: "


def _update_dicts() -> st.SearchStrategy:
    leaf = st.dictionaries(st.one_of(st.sampled_from(LEAVES), st.text(max_size=8)), VALUES, max_size=3)
    return st.dictionaries(st.one_of(st.sampled_from(TABLES), st.text(max_size=8)),
                           st.one_of(leaf, VALUES), min_size=1, max_size=3)


@st.composite
def config_requests(draw) -> tuple[str, bytes]:
    """(selector parameters, payload) of one config request."""
    kind = draw(st.sampled_from(["json"] * 5 + ["params"] * 3 + ["raw", "huge"]))
    if kind == "json":
        return "", json.dumps(draw(_update_dicts()), allow_nan=True).encode()
    if kind == "raw":
        return "", draw(st.one_of(st.binary(min_size=1, max_size=200),
                                  st.sampled_from([b"[]", b"1", b"null", b'"x"', b"{", b"{}" * 3])))
    if kind == "huge":
        n = draw(st.integers(100_000, 3_000_000))
        field = draw(st.sampled_from(["method", "bogus"]))
        return "", json.dumps({"decoder": {field: "x" * n}}).encode()
    keys = st.one_of(st.sampled_from([f"{t}.{leaf}" for t in TABLES[:4] for leaf in LEAVES]),
                     st.text(alphabet=SAFE.replace(" ", ""), min_size=1, max_size=12))
    values = st.one_of(st.text(alphabet=SAFE, max_size=20),
                       st.sampled_from(["2", "hard", "0.5", "true", "[1]", "{}", "null", "NaN", "1e999", "-3"]))
    params = draw(st.dictionaries(keys, values, min_size=1, max_size=3))
    return ";".join(f"{k}={v}" for k, v in params.items()), b""


class ConfigHarness:
    """A service (not capturing) with its zenoh sink on a loopback port, and a client session."""

    def __init__(self) -> None:
        import zenoh

        from edge.io.zenoh import make_config
        from edge.profiles import apply_update, load_profile
        from edge.io.publish import ZenohSink
        from edge.runtime.service import Service
        from edge.sensors.sim import SimSensor

        sys.path.insert(0, str(ROOT / "tests"))
        from _service_helpers import NumpyPipeline

        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            self.endpoint = f"tcp/127.0.0.1:{s.getsockname()[1]}"
        profile = apply_update(load_profile(TEST_PROFILE), {"zenoh": {"listen": [self.endpoint],
                                                                      "config_writes": True}})
        self.service = Service(profile, SimSensor(profile, poses=1), pipeline_factory=NumpyPipeline)
        self.sink = ZenohSink(profile, self.service)
        self.client = zenoh.open(make_config(connect=[self.endpoint]))
        self.key = profile.zenoh.key("config")
        time.sleep(0.3)

    def close(self) -> None:
        self.client.close()
        self.sink.close()


def check_config_request(h: ConfigHarness, params: str, payload: bytes, tally: Counter) -> None:
    from edge.io.zenoh import MAX_REASON_CHARS
    from edge.profiles import profile_to_dict

    before = h.service.profile
    counters = (h.service.counters.config_rejected, h.service.counters.config_updates)
    selector = h.key + (f"?{params}" if params else "")
    try:
        replies = list(h.client.get(selector, payload=payload or None, timeout=10.0))
    except Exception as exc:  # the client library refused to send it: nothing reached the service
        tally["refused by the zenoh client"] += 1
        if h.service.profile != before:
            raise Crash(f"running config changed after a request zenoh refused to send ({exc})") from None
        return
    if not replies:
        raise Crash(f"no reply to {selector[:80]!r} with {len(payload)} payload bytes")
    reply = replies[0]
    if reply.ok is not None:
        new = json.loads(reply.ok.payload.to_bytes())
        if new != profile_to_dict(h.service.profile) or h.service.counters.config_updates != counters[1] + 1:
            raise Crash("accepted update does not match the running profile / config_updates")
        tally["accepted"] += 1
        return
    text = reply.err.payload.to_bytes().decode(errors="replace")
    if not (_one_line(text) and text.startswith("config update rejected: ")
            and len(text) <= MAX_REASON_CHARS + 80):
        raise Crash(f"rejection not one short line: {len(text)} chars {text[:200]!r}")
    if h.service.profile != before:
        raise Crash(f"running config changed after a rejection: {text[:200]}")
    if h.service.counters.config_rejected != counters[0] + 1:
        raise Crash(f"config_rejected did not count the rejection: {text[:200]}")
    tally["huge rejected" if len(payload) > 100_000 else "rejected"] += 1


def fuzz_config(tally: Counter) -> None:
    h = ConfigHarness()
    try:
        @_settings("config")
        @given(config_requests())
        def prop(req: tuple[str, bytes]) -> None:
            check_config_request(h, req[0], req[1], tally)

        prop()
    finally:
        h.close()


# -- decode() ------------------------------------------------------------------------------------

CODES = ["nary8-3", "gray-10"]
DTYPES = [np.uint8, np.uint16, np.float32, np.float64, np.int16, np.bool_, np.complex64]
#: CI keeps to inputs whose numba kernels the rest of the suite compiles anyway (uint8; soft / hard):
#: each other dtype x method is a fresh compile of several seconds with a cold cache.
CI_DTYPES = [np.uint8, np.int16, np.bool_, np.complex64]
CI_CODES = ["gray-10"]   # binary, decoded by tests/test_decode.py too (q-ary codes have kernels of their own)
CI_METHODS = ["soft", "hard", "bogus"]
ODD = st.one_of(st.none(), st.integers(-300, 300), st.floats(allow_nan=True, allow_infinity=True))


def _array(draw, shape: tuple[int, ...], dtype: Any) -> np.ndarray:
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    dt = np.dtype(dtype)
    if dt.kind in "ui":
        hi = 255 if dt == np.uint8 else 4095
        a = rng.integers(0, hi + 1, shape).astype(dt)
    elif dt.kind == "b":
        a = rng.integers(0, 2, shape).astype(dt)
    else:
        a = rng.random(shape).astype(dt)
        if a.size and draw(st.booleans()):
            a.flat[draw(st.integers(0, a.size - 1))] = draw(st.sampled_from([np.nan, np.inf, -np.inf, -1.0]))
    return a


@st.composite
def decode_inputs(draw) -> tuple[Any, ...]:
    from edge.codes import get_code

    code = get_code(draw(st.sampled_from(CODES if os.environ.get("EDGE_FUZZ") == "full" else CI_CODES)))
    # one example in three is well formed (right n, shape and dtype), so that every budget
    # decodes some; the rest may break any of them
    formed = draw(st.integers(0, 2)) == 0
    h, w = draw(st.sampled_from([(1, 1), (1, 5), (5, 1), (4, 6), (7, 9)] if formed else
                                [(1, 1), (0, 3), (3, 0), (1, 5), (5, 1), (4, 6), (7, 9)]))
    n = code.n if formed or draw(st.integers(0, 4)) else draw(st.integers(0, 12))
    shape = (n, h, w) if formed else draw(st.sampled_from([(n, h, w)] * 6 + [(h, w), (n, h, w, 2), (n,)]))
    full = os.environ.get("EDGE_FUZZ") == "full"
    kinds = DTYPES if full else CI_DTYPES
    dtype = kinds[0] if formed else draw(st.sampled_from([kinds[0]] * 4 + kinds[1:] if not full else DTYPES[:4] * 3 + DTYPES[4:]))
    frames = _array(draw, shape, dtype)
    wb_shape = (h, w) if formed or draw(st.integers(0, 5)) else draw(st.sampled_from([(w, h), (h + 1, w), (h,), ()]))
    wb_dtype = dtype if formed or draw(st.integers(0, 5)) else draw(st.sampled_from(kinds))
    white = _array(draw, wb_shape, wb_dtype)
    black = _array(draw, wb_shape, wb_dtype)
    if draw(st.booleans()) and white.size:  # usually a usable white > black pair
        white = (np.zeros_like(white) + (255 if white.dtype == np.uint8 else 1)).astype(white.dtype)
        black = np.zeros_like(black)
    kw: dict[str, Any] = {}
    if draw(st.booleans()):
        kw["method"] = draw(st.sampled_from(["soft", "hard", "list", "median", "list+median", "bogus"]
                                            if full else CI_METHODS))
    for name in ("min_disparity", "max_disparity"):
        if draw(st.integers(0, 3)) == 0:
            kw[name] = draw(ODD)
    for name in ("sigma_r", "sigma_s", "min_contrast", "min_confidence", "t_low", "t_high"):
        if draw(st.integers(0, 5)) == 0:
            kw[name] = draw(st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.floats(0, 1)))
    for name in ("columns", "stripe", "bit_depth"):
        if draw(st.integers(0, 5)) == 0:
            kw[name] = draw(st.one_of(st.none(), st.integers(-3, 2000))) if name != "stripe" else draw(st.integers(-3, 2000))
    if draw(st.integers(0, 7)) == 0:
        kw["levels"] = draw(st.sampled_from(["refit", "calibration", "x"] if full else ["calibration", "x"]))
    if draw(st.integers(0, 7)) == 0:
        kw["inverse"] = _array(draw, shape, dtype)
    return frames, white, black, code, kw


def check_decode(frames: np.ndarray, white: np.ndarray, black: np.ndarray, code: Any, kw: dict[str, Any],
                 tally: Counter) -> None:
    from edge.decode import decode

    try:
        d = decode(frames, white, black, code, **kw)
    except ValueError as exc:
        if not _one_line(str(exc)):
            raise Crash(f"rejection not one line: {str(exc)[:300]!r}") from None
        tally["rejected"] += 1
        return
    except Exception as exc:
        raise Crash(f"decode crashed: {type(exc).__name__}: {str(exc)[:200]} "
                    f"(frames {frames.dtype} {frames.shape}, white {white.dtype} {white.shape}, {kw})") from exc
    hw = frames.shape[1:]
    if d.column.shape != hw or d.valid.shape != hw or d.confidence.shape != hw:
        raise Crash(f"decoded shapes {d.column.shape} / {d.valid.shape} for frames {frames.shape}")
    if not (np.all(d.column[d.valid] >= 0) and np.all(np.isfinite(d.confidence))):
        raise Crash("a valid pixel without a column, or a non-finite confidence")
    tally["decoded"] += 1


def fuzz_decode(tally: Counter) -> None:
    @_settings("decode")
    @given(decode_inputs())
    def prop(args: tuple[Any, ...]) -> None:
        check_decode(*args, tally)

    prop()


def large_stack(tally: Counter, *, height: int = 3000, width: int = 4000, factor: float = 4.0) -> dict[str, float]:
    """One (10, 3000, 4000) uint8 gray-10 stack, hard decoder, band of 64: traced memory peak vs input."""
    from edge.codes import get_code
    from edge.decode import decode

    code = get_code("gray-10")
    rng = np.random.default_rng(0)
    frames = rng.integers(0, 256, (code.n, height, width), dtype=np.uint8)
    white = np.full((height, width), 200, np.uint8)
    black = np.full((height, width), 20, np.uint8)
    decode(frames[:, :4, :4].copy(), white[:4, :4].copy(), black[:4, :4].copy(), code, method="hard")  # compile
    inputs = frames.nbytes + white.nbytes + black.nbytes
    tracemalloc.start()
    t0 = time.perf_counter()
    d = decode(frames, white, black, code, method="hard", min_disparity=-64, max_disparity=0)
    seconds = time.perf_counter() - t0
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    ok = d.column.shape == (height, width) and peak <= factor * inputs
    tally["large ok" if ok else "large over budget"] += 1
    return {"seconds": seconds, "peak_mb": peak / 1e6, "input_mb": inputs / 1e6, "ok": ok}


# -- rows -----------------------------------------------------------------------------------------

def _run(fn: Callable[[Counter], None]) -> tuple[Counter, str]:
    tally: Counter = Counter()
    try:
        fn(tally)
    except KeyboardInterrupt:
        raise
    except BaseException as exc:  # noqa: BLE001 - hypothesis re-raises the shrunk failure
        # the whole report on stderr: hypothesis' notes hold each falsifying example (and the blob
        # that reproduces it with @reproduce_failure), which the table row cannot
        traceback.print_exception(exc, file=sys.stderr)
        parts = exc.exceptions if isinstance(exc, BaseExceptionGroup) else (exc,)
        return tally, "; ".join(f"{type(e).__name__}: {' '.join(str(e).split())[:200]}" for e in parts)
    return tally, ""


def rows(full: bool) -> list[dict[str, Any]]:
    """One row per property (fault, trials, outcomes, target, met) for tools/fault_report.py."""
    os.environ.setdefault("NUMBA_CACHE_DIR", str(ROOT / ".numba_cache"))
    old = os.environ.get("EDGE_FUZZ")
    os.environ["EDGE_FUZZ"] = "full" if full else "ci"
    try:
        out = []
        for name, fn, what in (
                ("profiles", fuzz_profiles, "fuzzed profile TOML (load_profile + edge profiles check)"),
                ("config", fuzz_config, "fuzzed config updates over zenoh (JSON, ?key=value, MB payloads)"),
                ("decode", fuzz_decode, "fuzzed decode() inputs (shapes, dtypes, NaN/inf, empty, 1-pixel)")):
            tally, failure = _run(fn)
            outcomes = ", ".join(f"{n} {k}" for k, n in sorted(tally.items()))
            out.append({"fault": what, "trials": sum(tally.values()),
                        "outcomes": outcomes + (f"; FAILED: {failure}" if failure else "; 0 crashes"),
                        "target": "0 crashes; every rejection one clear line; running config unchanged",
                        "met": not failure})
        if full:
            tally: Counter = Counter()
            res = large_stack(tally)
            out.append({"fault": "decode() of a 4000 x 3000 x 10 uint8 stack (hard, band 64)", "trials": 1,
                        "outcomes": f"{res['seconds']:.1f} s, traced peak {res['peak_mb']:.0f} MB for "
                                    f"{res['input_mb']:.0f} MB of input",
                        "target": "decodes; traced memory peak <= 4x the input", "met": bool(res["ok"])})
        return out
    finally:
        if old is None:
            os.environ.pop("EDGE_FUZZ", None)
        else:
            os.environ["EDGE_FUZZ"] = old


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--full", action="store_true", help="large example budgets and the 4000 x 3000 stack")
    ap.add_argument("--seed", type=int, default=None, help="hypothesis' random seed (repeat a --full run)")
    ap.add_argument("--examples", type=int, default=None, help="examples per property instead of the budget's")
    args = ap.parse_args()
    if args.examples is not None and args.examples < 1:
        raise ValueError(f"--examples must be >= 1, got {args.examples}")
    RUN.update(seed=args.seed, examples=args.examples)
    t0 = time.monotonic()
    table = rows(args.full)
    print("| fault | trials | outcomes | target | met |\n|---|---|---|---|---|")
    for r in table:
        print(f"| {r['fault']} | {r['trials']} | {r['outcomes']} | {r['target']} | {'yes' if r['met'] else 'NO'} |")
    print(f"in {time.monotonic() - t0:.0f} s")
    return 0 if all(r["met"] for r in table) else 1


if __name__ == "__main__":
    from edge.cli import tool_main

    raise SystemExit(tool_main(main, __file__))
