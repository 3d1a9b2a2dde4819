"""Compile the kernels of every decoder variant a running service may switch to, before capture.

A live config update (``decoder.method``, ``edc.rounds``) builds a new pipeline; its numba kernels
compile on first use, which stalled one stack for 5.9 s (``hard``) and dropped 20 stacks.  So the
service warms up, before its sensor starts:

1. the profile's own pipeline (`DepthPipeline.warm_up`: a small synthetic stack, 8 x 64 pixels);
2. every *switchable variant* (`switchable_variants`): for a column-pattern profile each other
   decoder method that fits the projector (soft, hard, list, median) and, when ``edc.rounds`` is 0,
   the EDC stage (``edc.rounds = 1``, a synthetic stack through `process` with a synthetic masked
   capture, so the check and masked re-decode kernels compile too).

With a warm numba cache this is a second or two; with an empty cache (first start on a device)
it is minutes on a slow 2-core host, which is why the service only reports ``READY=1`` to systemd
after it.  So that a second core is not idle meanwhile, a profile pipeline still compiling after
`HELPER_AFTER_S` starts a *helper process* (`VariantHelper`) that compiles the variants
(`helper_order`) into numba's on-disk cache (processes share it safely under the lock of
`edge.numba_cache`); this process then warms each variant as before, loading what the helper
has saved and compiling the rest itself, so what is warmed, and what a failure refuses, does not
depend on the helper.  The helper is stopped when the warm-up ends (or stops), and exits by
itself when its parent is gone (its stdin closes).

A variant whose warm-up fails is not offered: `Service.update_config` refuses a switch
to it with the reason, and a method that does not fit the pipeline (see `WarmUpReport.refusal`).
An update accepted before or during warm-up is applied at the first stack, i.e. after every
variant compiled.
"""

from __future__ import annotations

import os
import pickle
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

#: Seconds the profile's own pipeline may take to warm up before a `VariantHelper` starts (a warm
#: numba cache loads a pipeline in a second or two: no helper then).
HELPER_AFTER_S = 5.0


def switchable_variants(profile) -> list[tuple[str, Any]]:
    """[(label, profile)] the live config may switch ``profile`` to, other than itself.

    Labels: ``"decoder.method=<m>"`` and ``"edc"`` (where the profile's code allows EDC rounds,
    `edge.profiles.settings._check_edc`).  Only column-pattern profiles have variants (the dots
    and curtain pipelines have one method each).
    """
    from edge.decode.settings import METHODS  # the decoder's own list (dots / curtain have one method each)
    from edge.device import pipeline_kind
    from edge.profiles import apply_update

    if pipeline_kind(profile) != "columns":
        return []
    out = [(f"decoder.method={m}", apply_update(profile, {"decoder": {"method": m}}, source="warm-up"))
           for m in METHODS if m != profile.decoder.method]
    if profile.edc.rounds == 0:
        from edge.profiles import ProfileError

        try:  # a code that detects no errors (or too long for the look-up) has no EDC variant
            out.append(("edc", apply_update(profile, {"edc": {"rounds": 1}}, source="warm-up")))
        except ProfileError:
            pass
    return out


def variant_label(old, new) -> list[str]:
    """Labels of `switchable_variants` that a change from ``old`` to ``new`` needs warmed."""
    labels = []
    if new.decoder.method != old.decoder.method:
        labels.append(f"decoder.method={new.decoder.method}")
    if new.edc.rounds > 0 and old.edc.rounds == 0:
        labels.append("edc")
    return labels


@dataclass
class WarmUpReport:
    """Seconds per warmed item (``"profile"`` = the running pipeline), failures (label -> reason),
    and whether a `VariantHelper` compiled the variants alongside (``helper``)."""

    seconds: dict[str, float] = field(default_factory=dict)
    failed: dict[str, str] = field(default_factory=dict)
    done: bool = False
    helper: bool = False

    @property
    def total_s(self) -> float:
        return float(sum(self.seconds.values()))

    def refusal(self, labels: list[str], base_labels: set[str]) -> str:
        """Why a change needing ``labels`` cannot be applied yet ('' = it can)."""
        for label in labels:
            if label.startswith("decoder.method=") and label not in base_labels:
                offered = ", ".join(x.split("=", 1)[1] for x in sorted(base_labels) if x.startswith("decoder.method="))
                return (f"{label} does not fit this profile's pipeline"
                        + (f" (it can switch to: {offered})" if offered else " (its method is fixed)"))
            if label in self.failed:
                return f"{label} is unavailable: its kernels failed to compile ({self.failed[label]})"
        # a variant not warmed yet is fine: warm-up finishes before the first stack is decoded
        return ""


def synthetic_stack(pipeline) -> tuple[Any, Callable[[int, int, np.ndarray], list[Any]]]:
    """A small (8 x 64) complete stack for a `DepthPipeline` and a masked-capture function that
    renders masked projector rows onto it (camera pixel x sees projector column x - d)."""
    from ..sensors.base import Frame
    from .assembly import Stack

    p = pipeline.profile
    dtype = np.uint8 if p.camera.bits == 8 else np.uint16
    full = pipeline.full_scale
    h, w = 8, 64
    mid = (p.decoder.min_disparity + p.decoder.max_disparity) // 2
    proj_col = np.clip(np.arange(w) - mid, 0, pipeline.columns * pipeline.stripe - 1)
    code = pipeline.code
    bits = code.codebook[proj_col // pipeline.stripe].T.astype(np.float64) / max(1, code.q - 1)  # (n, w)
    images = [0.1 * full + 0.7 * full * np.broadcast_to(b, (h, w)) for b in bits]
    images += [np.full((h, w), 0.8 * full), np.full((h, w), 0.1 * full)]
    L = pipeline.source_length
    frames = []
    for i, pf in enumerate(pipeline.schedule):
        img = images[min(i // L, len(images) - 1)]
        frames.append(Frame(np.ascontiguousarray(img).astype(dtype), i, 1000 + i, 1000.0, int(pf), 0))
    stack = Stack(0, tuple(frames), 0)

    def masked(stack_id: int, edc_round: int, rows: np.ndarray) -> list[Any]:
        rows = np.asarray(rows, dtype=np.float64)
        cols = np.clip(proj_col, 0, rows.shape[1] - 1)
        out = []
        for j, row in enumerate(rows):
            img = 0.1 * full + 0.7 * full * np.broadcast_to(row[cols] / max(1.0, row.max()), (h, w))
            out.append(Frame(img.astype(dtype), 100 + j, 2000 + j, 1000.0, int(j), stack_id))
        return out

    return stack, masked


def warm_pipeline(pipeline, *, edc: bool = False) -> float:
    """Warm one pipeline up (its own ``warm_up``; with ``edc`` a synthetic `process` through the
    EDC stage too).  Returns seconds."""
    t0 = time.perf_counter()
    warm = getattr(pipeline, "warm_up", None)
    if warm is not None:
        warm()
    if edc and hasattr(pipeline, "code"):
        stack, masked = synthetic_stack(pipeline)
        pipeline.process(stack, masked)
    return time.perf_counter() - t0


def warm_up_all(profile, factory: Callable[[Any], Any], pipeline: Any, *, variants: bool = True,
                report: WarmUpReport | None = None, should_stop: Callable[[], bool] = lambda: False,
                helper_after_s: float | None = HELPER_AFTER_S) -> WarmUpReport:
    """Warm ``pipeline`` (built from ``profile``) and, with ``variants``, every switchable variant
    (built with ``factory``).  Stops early when ``should_stop()`` turns true.  Fills ``report``.
    helper_after_s: where the profile's pipeline is still warming up after this many seconds, a
    `VariantHelper` compiles the variants alongside (only with the standard pipeline factory,
    see `VariantHelper.useful`; None: never)."""
    from .pipelines import make_pipeline

    report = report if report is not None else WarmUpReport()
    labelled = switchable_variants(profile) if variants else []
    helper = None
    timer = None
    if labelled and helper_after_s is not None and factory is make_pipeline and VariantHelper.useful():
        helper = VariantHelper(profile)
        timer = threading.Timer(helper_after_s, helper.start)
        timer.daemon = True
        timer.start()
    try:
        report.seconds["profile"] = warm_pipeline(pipeline, edc=profile.edc.rounds > 0)
        if timer is not None:
            timer.cancel()
        for label, variant in labelled:
            if should_stop():
                return report
            try:
                report.seconds[label] = warm_pipeline(factory(variant), edc=variant.edc.rounds > 0)
            except Exception as exc:  # a variant that cannot run is refused later, with this reason
                report.failed[label] = f"{type(exc).__name__}: {exc}"
        report.done = True
        return report
    finally:
        if timer is not None:
            timer.cancel()
        if helper is not None:
            report.helper = helper.stop()


class VariantHelper:
    """A child process (a fresh interpreter, `helper_main`) that warms every switchable variant of
    a profile (`helper_order`), so that their kernels land in numba's on-disk cache while this process
    compiles the profile's own pipeline.  The profile goes to it pickled on its stdin, which then
    stays open: the child exits when it closes (this process gone).  Its output is discarded.

    `start` and `stop` may race (a timer starts it): once stopped it does not start."""

    def __init__(self, profile) -> None:
        self.profile = profile
        self._lock = threading.Lock()
        self._proc: subprocess.Popen | None = None
        self._stopped = False

    @staticmethod
    def useful() -> bool:
        """A second CPU to compile on, numba compiling at all, and its cache lock in place (no
        ``fcntl``: two processes saving into one cache are not safe, `edge.numba_cache`)."""
        from .. import numba_cache

        try:
            cpus = len(os.sched_getaffinity(0))
        except AttributeError:  # not on Linux
            cpus = os.cpu_count() or 1
        return cpus >= 2 and numba_cache.fcntl is not None and os.environ.get("NUMBA_DISABLE_JIT", "0") in ("", "0")

    def start(self) -> None:
        with self._lock:
            if self._stopped or self._proc is not None:
                return
            # the folder above the edge package first on the child's path: it imports this edge
            # whether installed or run from a checkout
            root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
            env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in (root, os.environ.get("PYTHONPATH")) if p))
            try:
                self._proc = subprocess.Popen(
                    [sys.executable, "-c", "from edge.runtime.warmup import helper_main; helper_main()"],
                    stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env)
                self._proc.stdin.write(pickle.dumps(self.profile))
                self._proc.stdin.flush()
            except OSError:  # no helper: this process compiles everything, as without one
                self._kill()

    def stop(self) -> bool:
        """Stop the child (if it started); returns whether it had started."""
        with self._lock:
            self._stopped = True
            started = self._proc is not None
            self._kill()
            return started

    def _kill(self) -> None:
        proc, self._proc = self._proc, None
        if proc is None:
            return
        if proc.poll() is None:
            proc.terminate()
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        if proc.stdin is not None:
            try:
                proc.stdin.close()
            except OSError:
                pass


def helper_order(labelled: list[tuple[str, Any]]) -> list[tuple[str, Any]]:
    """The order the helper warms the variants in: ``decoder.method=hard`` first (its kernels share
    nothing with a soft decoder's, so it compiles while the parent compiles the profile's), then
    the rest last first (the parent warms them first first: the two meet in the middle)."""
    hard = [x for x in labelled if x[0] == "decoder.method=hard"]
    return hard + [x for x in reversed(labelled) if x[0] != "decoder.method=hard"]


def helper_main() -> None:
    """`VariantHelper`'s child: read the pickled profile from stdin, exit once stdin closes (the
    parent gone), warm each switchable variant in `helper_order`; a variant that fails is
    skipped (the parent reports it)."""
    from .pipelines import make_pipeline

    stream = sys.stdin.buffer
    profile = pickle.load(stream)

    def watch() -> None:
        stream.read()  # returns at EOF: the parent closed the pipe or is gone
        os._exit(0)

    threading.Thread(target=watch, name="edge-warmup-helper-watch", daemon=True).start()
    for _label, variant in helper_order(switchable_variants(profile)):
        try:
            warm_pipeline(make_pipeline(variant), edc=variant.edc.rounds > 0)
        except Exception:
            continue
