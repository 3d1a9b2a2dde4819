"""Where the depth service's resident memory goes: a breakdown table, one process, under 2 minutes.

    python tools/memory_service.py [--profile sim-dlp] [--stacks 30] [--warmup-stacks 5] [--poses 8]
                                   [--no-zenoh] [--subscribe] [--malloc-arenas 0] [--top 6]

Builds the service as ``edge run --poses 8 --quiet`` does (`edge.commands.run.build_service`:
simulated sensor at real time, zenoh on a free loopback port) in THIS process and measures it in
stages, each row the RSS (VmRSS) it adds, so the rows add up to the RSS at the end:

* the interpreter and numpy (RSS after ``import numpy``), numba + llvmlite, the rest of the imports
  (zenoh, mcap, the edge commands);
* numba's JIT runtime (LLVM initialised by compiling one trivial function, the parallel backend by
  one trivial ``prange``);
* the sensor, the service objects and the zenoh session (``build_service``);
* the decoder kernels loaded from the numba cache or compiled (``Service.warm_up``);
* the run (``--warmup-stacks`` + ``--stacks`` stacks decoded): the arrays alive at the last stack by
  owner (a walk of the service's objects counting every array buffer once: pre-rendered sensor
  poses, the render queue, the stack being assembled, the stack queue, the last result, the
  pipeline, the sinks; "other arrays" are the ones only the garbage collector reaches, e.g. module
  caches), the free memory the C allocator keeps (glibc ``mallinfo2``: free bytes in its arenas),
  and the rest (Python objects, thread stacks, allocator overhead).

Below the table: the peak (VmHWM), the allocator (arenas, in use, kept free; the RSS after
``malloc_trim(0)`` shows how much of the kept memory was releasable), the bounds of the queues, and
the decoder's working set of one stack (tracemalloc peak of ``pipeline.process`` on the last stack,
numpy allocations) with the lines that hold most of it at that peak.  ``--subscribe`` runs a zenoh
subscriber in a child process so depth really flows (as in tools/soak_service.py).

Figures depend on the machine (its core count sets glibc's default arena count) and on load.
"""

from __future__ import annotations

import argparse
import ctypes
import ctypes.util
import gc
import os
import re
import subprocess
import sys
import tempfile
import time
import types
import weakref
from collections import defaultdict, deque
from pathlib import Path
from typing import Any, Iterable

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from _ports import free_port  # noqa: E402
MB = float(1 << 20)


# ----------------------------------------------------------------------------- measurements
def status_mb(field: str = "VmRSS") -> float:
    """/proc/self/status ``field`` (VmRSS, VmHWM) in MB; NaN where there is no /proc."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith(field + ":"):
                return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return float("nan")


class _MallInfo2(ctypes.Structure):
    _fields_ = [(n, ctypes.c_size_t) for n in
                ("arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks", "fsmblks", "uordblks", "fordblks",
                 "keepcost")]


def _libc() -> Any:
    """glibc with mallinfo2 / malloc_info / malloc_trim, or None (another C library)."""
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        libc.mallinfo2.restype = _MallInfo2
        libc.malloc_info  # noqa: B018  (present on glibc only)
        return libc
    except (OSError, AttributeError):
        return None


LIBC = _libc()


def malloc_state() -> dict[str, float] | None:
    """glibc allocator totals in MB: ``system`` (arena bytes taken from the OS), ``in_use``, ``free``
    (kept in the arenas), ``mmapped`` (large blocks, returned on free), and ``arenas``; None off glibc."""
    if LIBC is None:
        return None
    m = LIBC.mallinfo2()
    return {"system": m.arena / MB, "in_use": m.uordblks / MB, "free": m.fordblks / MB, "mmapped": m.hblkhd / MB,
            "arenas": float(arena_count())}


def arena_count() -> int:
    """Number of glibc malloc arenas (``<heap nr=...>`` entries of ``malloc_info``); 0 off glibc."""
    if LIBC is None:
        return 0
    with tempfile.TemporaryFile("w+b") as f:
        LIBC.fdopen.restype = ctypes.c_void_p
        stream = LIBC.fdopen(os.dup(f.fileno()), b"w")
        LIBC.malloc_info(0, ctypes.c_void_p(stream))
        LIBC.fclose(ctypes.c_void_p(stream))
        f.seek(0)
        return len(re.findall(rb'<heap nr="\d+">', f.read()))


# ----------------------------------------------------------------------------- array census
_LEAVES = (str, bytes, bytearray, int, float, complex, bool, type(None), type, types.ModuleType,
           types.FunctionType, types.BuiltinFunctionType, types.MethodType, types.CodeType)


def _is_array(obj: Any) -> bool:
    """ndarray test by type (``isinstance`` on a dead weak proxy raises)."""
    return issubclass(type(obj), np.ndarray)


def _buffer_root(a: np.ndarray) -> np.ndarray:
    """The array that owns ``a``'s memory (following views' ``base``)."""
    while isinstance(a.base, np.ndarray):
        a = a.base
    return a


def _children(obj: Any) -> Iterable[Any]:
    if isinstance(obj, dict):
        return list(obj.values())
    if isinstance(obj, (list, tuple, set, frozenset, deque)):
        return list(obj)
    out = []
    queue_items = getattr(obj, "queue", None)  # queue.Queue
    if isinstance(queue_items, deque):
        out.append(queue_items)
    d = getattr(obj, "__dict__", None)
    if isinstance(d, dict):
        out.extend(d.values())
    for name in getattr(type(obj), "__slots__", ()):
        if hasattr(obj, name):
            out.append(getattr(obj, name))
    return out


def arrays_under(root: Any, seen: set[int], *, depth: int = 8) -> dict[int, np.ndarray]:
    """{id: array} of the buffer-owning arrays reachable from ``root`` through attributes and
    containers (not through modules, classes, functions or objects already in ``seen``); adds
    what it visits and every buffer it counts to ``seen``, so a later call (or a view of a
    counted buffer) does not count that buffer again."""
    found: dict[int, np.ndarray] = {}
    todo = [(root, 0)]
    while todo:
        obj, level = todo.pop()
        kind = type(obj)
        if id(obj) in seen or issubclass(kind, _LEAVES) or kind in weakref.ProxyTypes:
            continue
        seen.add(id(obj))
        if _is_array(obj):
            base = _buffer_root(obj)
            if base is obj or id(base) not in seen:  # a view of a buffer counted before adds nothing
                found[id(base)] = base
                seen.add(id(base))
            continue
        if level < depth:
            todo.extend((child, level + 1) for child in _children(obj))
    return found


def gc_arrays(exclude: set[int]) -> dict[int, np.ndarray]:
    """Buffer-owning arrays referred to by any object the garbage collector tracks, minus ``exclude``."""
    gc.collect()
    found: dict[int, np.ndarray] = {}
    for obj in gc.get_objects():
        for ref in gc.get_referents(obj):
            if _is_array(ref):
                base = _buffer_root(ref)
                if id(base) not in exclude:
                    found[id(base)] = base
    return found


def nbytes(arrays: dict[int, np.ndarray]) -> float:
    return sum(a.nbytes for a in arrays.values()) / MB


def by_shape(arrays: dict[int, np.ndarray], top: int) -> str:
    """The ``top`` largest (shape, dtype) groups of ``arrays``: 'N x shape dtype MB'."""
    groups: dict[tuple, list[int]] = defaultdict(lambda: [0, 0])
    for a in arrays.values():
        g = groups[(a.shape, str(a.dtype))]
        g[0] += 1
        g[1] += a.nbytes
    best = sorted(groups.items(), key=lambda kv: -kv[1][1])[:top]
    return ", ".join(f"{n} x {shape} {dtype} {size / MB:.1f}" for (shape, dtype), (n, size) in best)


def census(service: Any, exclude: set[int]) -> list[tuple[str, dict[int, np.ndarray]]]:
    """[(owner, arrays)] of the running service, every buffer counted once (first owner wins),
    arrays in ``exclude`` (alive before the run) left out."""
    sensor = service.sensor
    owners: list[tuple[str, Any]] = [
        ("sensor: pre-rendered poses (--poses; the simulator only)", getattr(sensor, "_pose_cache", None)),
        ("sensor: render queue, scenes, pending frames",
         [getattr(sensor, k, None) for k in ("_rendered", "_pending", "_scenes")]),
        ("assembler: the stack being assembled", service.assembler),
        (f"stack queue (capacity {service.queue.capacity})", service.queue),
        ("last result (kept for the status)", service.last_result),
        ("pipeline (code tables, settings)", service.pipeline),
        ("sinks (zenoh publisher, console)", service.sinks),
        ("recorder", service.recorder),
    ]
    seen: set[int] = set(exclude)  # arrays_under adds every buffer it counts: the first owner wins
    out = [(label, arrays_under(root, seen)) for label, root in owners]
    out.append(("other arrays (module caches, reached by gc only)", gc_arrays(seen)))
    return out


# ----------------------------------------------------------------------------- decoder working set
def decode_working_set(pipeline: Any, stack: Any, top: int) -> tuple[float, list[tuple[float, str]]]:
    """(tracemalloc peak MB of ``pipeline.process(stack)``, [(MB, 'file:line')] held at that peak)."""
    import tracemalloc

    tracemalloc.start(1)
    best: list[Any] = [0, None]

    def hook(frame: Any, event: str, arg: Any) -> None:  # snapshot whenever the traced total grows by 1 MB
        if event in ("return", "c_return"):
            current = tracemalloc.get_traced_memory()[0]
            if current > best[0] + (1 << 20):
                best[0], best[1] = current, tracemalloc.take_snapshot()

    sys.setprofile(hook)
    try:
        pipeline.process(stack)
    finally:
        sys.setprofile(None)
        peak = tracemalloc.get_traced_memory()[1] / MB
        tracemalloc.stop()
    lines: list[tuple[float, str]] = []
    if best[1] is not None:
        snap = best[1].filter_traces([tracemalloc.Filter(False, tracemalloc.__file__)])
        for stat in snap.statistics("lineno")[:top]:
            where = stat.traceback[0]
            name = where.filename
            name = name[name.rfind("edge" + os.sep):] if "edge" + os.sep in name else os.path.basename(name)
            lines.append((stat.size / MB, f"{name}:{where.lineno}"))
    return peak, lines


# ----------------------------------------------------------------------------- the run
def subscriber(port: int, device: str, seconds: float) -> subprocess.Popen:
    """A child process that receives depth from the service for ``seconds``."""
    code = ("import time\nfrom edge.io.zenoh import DepthSubscriber\n"
            f"s = DepthSubscriber({device!r}, connect=['tcp/127.0.0.1:{port}'])\n"
            f"end = time.monotonic() + {seconds}\n"
            "while time.monotonic() < end:\n    s.receive(timeout=0.2, confidence_wait=0.0)\ns.close()\n")
    return subprocess.Popen([sys.executable, "-c", code], cwd=ROOT, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)


def warm_numba_runtime() -> None:
    """Compile one trivial function and one trivial parallel function (LLVM and the parallel backend)."""
    import numba

    @numba.njit(cache=False)
    def one(x):
        return x + 1

    @numba.njit(parallel=True, cache=False)
    def total(x):
        s = 0.0
        for i in numba.prange(x.size):
            s += x[i]
        return s

    one(1)
    total(np.ones(4))


def numba_kernels() -> tuple[int, int]:
    """(dispatchers with a compiled overload, overloads) alive in this process."""
    from numba.core.dispatcher import Dispatcher

    with_code = [d for d in gc.get_objects() if issubclass(type(d), Dispatcher) and d.overloads]
    return len(with_code), sum(len(d.overloads) for d in with_code)


def keep_last_stack(service: Any, holder: dict[str, Any]) -> None:
    """Wrap the service pipeline's ``process`` so that ``holder['stack']`` is the last stack decoded."""
    pipeline = service.pipeline
    process = pipeline.process

    def process_and_keep(stack: Any, masked_capture: Any = None) -> Any:
        holder["stack"] = stack
        return process(stack, masked_capture)

    pipeline.process = process_and_keep
    holder["pipeline"] = pipeline
    holder["process"] = process


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--profile", default="sim-dlp", help="firmware profile name or TOML path (default sim-dlp)")
    ap.add_argument("--stacks", type=int, default=30,
                    help="stacks decoded after the warm-up stacks before the arrays are counted (default 30)")
    ap.add_argument("--warmup-stacks", type=int, default=5,
                    help="stacks decoded first, so the allocator reaches its steady size (default 5)")
    ap.add_argument("--poses", type=int, default=8,
                    help="pre-rendered poses of the simulated scene, as tools/soak_service.py (default 8)")
    ap.add_argument("--no-zenoh", action="store_true", help="no zenoh session (default: one, on a free port)")
    ap.add_argument("--subscribe", action="store_true",
                    help="a zenoh subscriber in a child process receives the depth (default: none)")
    ap.add_argument("--malloc-arenas", type=int, default=0, metavar="N",
                    help="limit glibc's malloc arenas to N (mallopt M_ARENA_MAX) before the service starts, "
                         "to see what the per-thread arenas keep; 0 = glibc's own limit, 8 per core (default 0)")
    ap.add_argument("--top", type=int, default=6, help="rows of the per-line and per-shape lists (default 6)")
    args = ap.parse_args(argv)
    if args.stacks < 1 or args.warmup_stacks < 0:
        raise ValueError(f"--stacks must be >= 1 and --warmup-stacks >= 0, got {args.stacks} and {args.warmup_stacks}")
    if args.poses < 0:
        raise ValueError(f"--poses must be >= 0, got {args.poses}")
    if args.malloc_arenas < 0:
        raise ValueError(f"--malloc-arenas must be >= 0, got {args.malloc_arenas}")
    if args.top < 1:
        raise ValueError(f"--top must be >= 1, got {args.top}")
    return args


class Table:
    """Rows (component, MB, how measured) of RSS increments."""

    def __init__(self) -> None:
        self.rows: list[tuple[str, float, str]] = []
        self.last = status_mb()

    def step(self, label: str, how: str) -> float:
        """Row for the RSS added since the previous step."""
        now = status_mb()
        self.rows.append((label, now - self.last, how))
        self.last = now
        return now

    def add(self, label: str, mb: float, how: str) -> None:
        self.rows.append((label, mb, how))

    def print(self) -> None:
        width = max(len(r[0]) for r in self.rows)
        print(f"| {'component':<{width}} | {'MB':>7} | how measured |")
        print(f"|{'-' * (width + 2)}|{'-' * 9}|---|")
        for label, mb, how in self.rows:
            print(f"| {label:<{width}} | {mb:7.1f} | {how} |")


def run_service(args: argparse.Namespace, table: Table) -> dict[str, Any]:
    """Build, warm up and run the service as ``edge run`` does; fill ``table``; return what the
    report below the table needs."""
    from edge.cli import build_parser
    from edge.commands.run import build_service, load_run_profile

    table.step("zenoh, mcap and edge modules (import)", "RSS added by importing the edge commands")
    warm_numba_runtime()
    table.step("numba JIT runtime (LLVM, parallel backend)", "RSS added by compiling a trivial @njit and prange")
    port = free_port()
    run_args = ["run", "--profile", args.profile, "--poses", str(args.poses), "--quiet", "--listen",
                f"tcp/127.0.0.1:{port}"] + (["--no-zenoh"] if args.no_zenoh else [])
    cli = build_parser().parse_args(run_args)
    profile = load_run_profile(cli)
    service = build_service(profile, cli, sinks=[])
    try:
        return measure_run(args, table, service, port)
    finally:
        service.close()  # a no-op after run; closes zenoh when something above failed


def measure_run(args: argparse.Namespace, table: Table, service: Any, port: int) -> dict[str, Any]:
    """`run_service` from the built service on: warm-up, the run and its census."""
    table.step("sensor, service objects" + ("" if args.no_zenoh else ", zenoh session"), "RSS added by build_service")
    t0 = time.perf_counter()
    if not service.warm_up():
        raise RuntimeError("warm-up was stopped")
    dispatchers, overloads = numba_kernels()
    table.step(f"decoder kernels ({dispatchers} numba dispatchers, {overloads} overloads)",
               f"RSS added by Service.warm_up ({time.perf_counter() - t0:.1f} s)")
    gc.collect()
    alive_before = gc_arrays(set())
    malloc_warm = malloc_state()
    holder: dict[str, Any] = {}
    keep_last_stack(service, holder)
    target = args.warmup_stacks + args.stacks
    result: dict[str, Any] = {"census": None}

    def on_tick(svc: Any) -> None:
        if result["census"] is None and svc.counters.stacks_decoded >= target:
            result["rss"] = status_mb()
            result["malloc"] = malloc_state()
            result["census"] = census(svc, set(alive_before))
            svc.stop()

    child = subscriber(port, service.profile.zenoh.device, 30.0 + 0.5 * target) if args.subscribe and not args.no_zenoh else None
    try:
        status = service.run(stacks=target + 1000, seconds=60.0 + target, on_tick=on_tick)
    finally:
        if child is not None:
            child.kill()
            child.wait()
    if result["census"] is None:
        raise RuntimeError(f"the service decoded {status['stacks_decoded']} of {target} stacks: {status.get('errors')}")
    result.update(status=status, service=service, holder=holder, malloc_warm=malloc_warm)
    return result


def run_rows(table: Table, result: dict[str, Any], top: int) -> None:
    """The rows of the run: arrays by owner, memory the allocator keeps free, the rest."""
    grown = result["rss"] - table.last
    counted = 0.0
    for label, arrays in result["census"]:
        mb = nbytes(arrays)
        counted += mb
        how = f"array buffers alive at the last stack ({len(arrays)})"
        if label.startswith("other arrays") and arrays:
            how += ": " + by_shape(arrays, min(top, 3))
        table.add("run: " + label, mb, how)
    warm, end = result["malloc_warm"], result["malloc"]
    kept = 0.0
    if warm is not None and end is not None:
        kept = end["free"] - warm["free"]
        table.add("run: free memory kept by malloc", kept,
                  f"glibc mallinfo2 free bytes, at the last stack minus after warm-up ({end['arenas']:.0f} arenas; "
                  f"freed pages need not be resident, so the next row can be negative)")
    table.add("run: other (Python objects, thread stacks, allocator overhead)", grown - counted - kept,
              "RSS added by the run minus the rows above")
    table.add("total resident (VmRSS at the last stack)", result["rss"], "/proc/self/status")


def report(result: dict[str, Any], args: argparse.Namespace) -> None:
    """Lines below the table: peak, allocator, queue bounds, the decoder's working set."""
    service, holder = result["service"], result["holder"]
    print(f"\npeak resident (VmHWM): {status_mb('VmHWM'):.1f} MB; stacks decoded {result['status']['stacks_decoded']}, "
          f"dropped {result['status']['stacks_dropped']}, decode p50 {result['status']['decode_ms_p50']} ms")
    end = result["malloc"]
    if end is not None:
        before = status_mb()
        LIBC.malloc_trim(0)
        print(f"malloc ({args.arena_limit}): {end['arenas']:.0f} arenas, {end['system']:.1f} MB taken "
              f"from the OS, {end['in_use']:.1f} MB in use, {end['free']:.1f} MB kept free, {end['mmapped']:.1f} MB "
              f"in mmapped blocks; malloc_trim(0) now (service stopped) takes RSS {before:.1f} -> {status_mb():.1f} MB")
    sensor = service.sensor
    rendered = getattr(getattr(sensor, "_rendered", None), "maxsize", None)
    recorder = service.recorder
    print(f"bounds: stack queue {service.queue.capacity} stack(s) (drop oldest); sensor render queue "
          f"{rendered if rendered is not None else 'n/a'} stacks; recorder queue "
          f"{getattr(recorder, 'max_queued_bytes', 0) / MB:.0f} MB" if recorder is not None else
          f"bounds: stack queue {service.queue.capacity} stack(s) (drop oldest); sensor render queue "
          f"{rendered if rendered is not None else 'n/a'} stacks; no recorder")
    stack = holder.get("stack")
    if stack is None:
        return
    holder["pipeline"].process = holder["process"]
    images = sum(np.asarray(f.image).nbytes for f in stack.frames) / MB
    peak, lines = decode_working_set(holder["pipeline"], stack, args.top)
    print(f"decoder working set of one stack ({len(stack.frames)} frames, {images:.1f} MB of images): "
          f"{peak:.1f} MB tracemalloc peak (numpy) over pipeline.process; held at the peak:")
    for mb, where in lines:
        print(f"  {mb:6.1f} MB  {where}")


def limit_arenas(n: int) -> bool:
    """glibc ``mallopt(M_ARENA_MAX, n)`` (n > 0; before threads start); False off glibc or for 0."""
    if n <= 0 or LIBC is None:
        return False
    return bool(LIBC.mallopt(-8, n))  # M_ARENA_MAX (malloc.h)


def main() -> int:
    args = parse_args()
    limited = limit_arenas(args.malloc_arenas)
    args.arena_limit = f"M_ARENA_MAX={args.malloc_arenas}" if limited else "glibc's default arena limit"
    t0 = time.monotonic()
    table = Table()
    table.add("Python interpreter and numpy", table.last, "RSS after import numpy")
    import numba  # noqa: F401

    table.step("numba and llvmlite (import)", "RSS added by import numba")
    result = run_service(args, table)
    run_rows(table, result, args.top)
    print(f"memory of the depth service, profile {args.profile}, poses {args.poses}, "
          f"{args.warmup_stacks} + {args.stacks} stacks" + (", subscriber" if args.subscribe else "") + "\n")
    table.print()
    report(result, args)
    print(f"\n({time.monotonic() - t0:.0f} s)")
    return 0


if __name__ == "__main__":
    from edge.cli import tool_main

    raise SystemExit(tool_main(main, __file__))
