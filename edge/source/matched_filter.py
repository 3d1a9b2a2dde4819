"""Matched filters for source-coded light: frame stacks (`despread`) and event streams (`filter_events`).

Frame sensors: every projection symbol was spread over L slots (`edge.codes.source.spread`).  Per pixel
and symbol the L received slot values r are correlated with the zero-mean template
``s = bits - weight/L``:

    amplitude   a   = <s, r> / <s, s>          (own light in the input's units; ambient cancels)
    correlation rho = <s, r> / (|s| |r - mean r|)   (Pearson, in [-1, 1]; 0 for a constant pixel)

A symbol is accepted when ``rho >= threshold`` (``|rho|`` for ``off="complement"``) and its output is
``a``; rejected symbols output 0, the value a dark ("off") symbol has, so the decoder sees foreign
light as absent.  With ``off="complement"`` an "off" symbol gives ``-a`` (antipodal); de-spread white
and black calibration frames the same way and the decoder's (I - black) / (white - black) works as is.

Event sensors: own events sit at the code's edges.  Events are binned per pixel by slot (the slot
whose start is the nearest earlier boundary, shifted by ``guard_us`` so edge events with latency and
jitter land in the slot they belong to), signed counts are summed per period of L slots, and a pixel's
events in a period are kept when the cosine between its counts and the code's transitions
(``bits[i] - bits[i-1]``) is >= threshold and the event's polarity matches its slot's edge.

Counts are int32, one accumulator of H*W*L counts per thread: exact (to wrap, one pixel's slot
would need 2**31 events in one call, 28 GB of input).  int16 would wrap past 32,767 events of one
polarity in one pixel's slot (a hot pixel, a long slot, no refractory time) and turn the pixel's
own events into rejected ones; a saturating count would still bend its cosine.  The cost is 4
bytes per pixel and slot per thread: 9.8 MB per thread for the largest event profile (640 x 480,
L = 8; 4.9 MB in int16), 79 MB per thread for a 64-slot code (the longest ``code.source`` a
profile takes) at that size.
Slots are int16, so codes of at most `MAX_EVENT_CODE_LENGTH` slots are taken.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np
from numba import njit, prange

from ..codes.source import OFF_MODES, SourceCode, source_code
from ..numba_cache import install as _install_cache_lock
from .events import EVENT_DTYPE, check_events

_install_cache_lock()  # before any kernel of this module is compiled or loaded (edge.numba_cache)

DEFAULT_THRESHOLD = 0.85
#: Event default: ``10100010`` against a plain ``10`` square wave at the same slot rate reaches a
#: cosine of 0.866, so event filters need a higher bar than frame filters.
DEFAULT_EVENT_THRESHOLD = 0.92
#: Longest code the event filter takes: its slots 0..L-1 are int16 (`EventFilterResult.slot`).
MAX_EVENT_CODE_LENGTH = int(np.iinfo(np.int16).max) + 1


@dataclass(frozen=True)
class Despread:
    """Output of `despread`.

    frames: float32 (m, H, W) own-light amplitude per symbol (input units), 0 where rejected.
    accepted: bool (m, H, W) symbol passed the correlation test.
    correlation: float32 (m, H, W) normalised correlation rho.
    """

    frames: np.ndarray
    accepted: np.ndarray
    correlation: np.ndarray


@njit(cache=True, parallel=True)
def _despread_kernel(frames, template, threshold, min_amplitude, signed, out, acc, corr):  # pragma: no cover - numba
    n_slots, h, w = frames.shape
    L = template.size
    m = n_slots // L
    s2 = 0.0
    for j in range(L):
        s2 += template[j] * template[j]
    s_norm = np.sqrt(s2)
    for y in prange(h):
        dot = np.empty(w, np.float64)
        tot = np.empty(w, np.float64)
        sq = np.empty(w, np.float64)
        for i in range(m):
            for x in range(w):
                dot[x] = 0.0
                tot[x] = 0.0
                sq[x] = 0.0
            for j in range(L):
                sj = template[j]
                row = frames[i * L + j, y]
                for x in range(w):
                    v = np.float64(row[x])
                    dot[x] += sj * v
                    tot[x] += v
                    sq[x] += v * v
            for x in range(w):
                var = sq[x] - tot[x] * tot[x] / L
                a = dot[x] / s2
                rho = 0.0
                if var > 1e-12 * (sq[x] + 1e-30):
                    rho = dot[x] / (s_norm * np.sqrt(var))
                ok = rho >= threshold and a >= min_amplitude
                if signed:
                    ok = abs(rho) >= threshold and abs(a) >= min_amplitude
                acc[i, y, x] = ok
                corr[i, y, x] = rho
                out[i, y, x] = a if ok else 0.0


def _check_frames(frames: np.ndarray, code: SourceCode) -> np.ndarray:
    f = np.asarray(frames)
    if f.ndim != 3:
        raise ValueError(f"frames must be (m*L, H, W), got shape {f.shape}")
    if f.shape[0] == 0 or f.shape[0] % code.length:
        raise ValueError(
            f"frame count must be a positive multiple of the code length L={code.length} "
            f"(code {code.string}), got {f.shape[0]} frames"
        )
    if f.dtype not in (np.uint8, np.uint16, np.float32, np.float64):
        raise ValueError(f"frames must be uint8, uint16, float32 or float64, got {f.dtype}")
    return np.ascontiguousarray(f)


def despread(
    frames: np.ndarray,
    code: "SourceCode | str",
    *,
    threshold: float = DEFAULT_THRESHOLD,
    min_amplitude: float = 0.0,
    off: str = "dark",
) -> Despread:
    """Matched filter for a frame sensor: (m*L, H, W) slot frames -> (m, H, W) de-spread frames.

    frames: uint8 / uint16 / float32 / float64, slot ``i*L + j`` = symbol i, code slot j.
    threshold: accept when the correlation reaches it (own noiseless light gives 1); choose it above the
        worst unsynchronised interference of your family (`edge.codes.source.worst_interference`).
    min_amplitude: also require ``a >= min_amplitude`` (input units), e.g. a few noise sigmas.
    off: how the device spread "off" symbols: ``"dark"`` (accept positive correlation only) or
        ``"complement"`` (accept |rho|, output signed amplitude).
    Runs a parallel numba kernel (call from one thread at a time).
    """
    code = source_code(code)
    if off not in OFF_MODES:
        raise ValueError(f"off must be one of {OFF_MODES}, got {off!r}")
    if not -1.0 <= threshold <= 1.0:
        raise ValueError(f"threshold must be in [-1, 1], got {threshold}")
    f = _check_frames(frames, code)
    m, h, w = f.shape[0] // code.length, f.shape[1], f.shape[2]
    out = np.empty((m, h, w), np.float32)
    acc = np.empty((m, h, w), np.bool_)
    corr = np.empty((m, h, w), np.float32)
    _despread_kernel(f, code.template, float(threshold), float(min_amplitude), off == "complement", out, acc, corr)
    return Despread(out, acc, corr)


def despread_numpy(
    frames: np.ndarray, code: "SourceCode | str", *, threshold: float = DEFAULT_THRESHOLD,
    min_amplitude: float = 0.0, off: str = "dark",
) -> Despread:
    """Plain-numpy reference of `despread` (same result; the baseline in tools/bench_matched_filter.py)."""
    code = source_code(code)
    if off not in OFF_MODES:
        raise ValueError(f"off must be one of {OFF_MODES}, got {off!r}")
    if not -1.0 <= threshold <= 1.0:
        raise ValueError(f"threshold must be in [-1, 1], got {threshold}")
    f = _check_frames(frames, code)
    L = code.length
    r = f.reshape((-1, L) + f.shape[1:]).astype(np.float64)
    s = code.template.reshape((1, L, 1, 1))
    dot = (r * s).sum(axis=1)
    var = (r * r).sum(axis=1) - r.sum(axis=1) ** 2 / L
    s2 = float((code.template**2).sum())
    a = dot / s2
    sq = (r * r).sum(axis=1)
    ok_var = var > 1e-12 * (sq + 1e-30)
    rho = np.where(ok_var, dot / (np.sqrt(s2) * np.sqrt(np.where(ok_var, var, 1.0))), 0.0)
    if off == "complement":
        acc = (np.abs(rho) >= threshold) & (np.abs(a) >= min_amplitude)
    else:
        acc = (rho >= threshold) & (a >= min_amplitude)
    return Despread(np.where(acc, a, 0.0).astype(np.float32), acc, rho.astype(np.float32))


# --------------------------------------------------------------------------------------------
# Events
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class EventFilterResult:
    """Output of `filter_events` / `EventMatchedFilter.push`.

    keep: bool (N,) per input event (False for dropped out-of-sensor events).
    period: int64 (N,) index of the code period (L slots) each event falls in.
    slot: int16 (N,) slot of the event inside its period (0..L-1).
    dropped_out_of_bounds: events whose x >= width or y >= height (ignored, counted).
    """

    keep: np.ndarray
    period: np.ndarray
    slot: np.ndarray
    dropped_out_of_bounds: int

    @property
    def kept(self) -> int:
        return int(self.keep.sum())


@njit(cache=True)
def _first_unsorted(t):  # pragma: no cover - numba
    for i in range(1, t.size):
        if t[i] < t[i - 1]:
            return i
    return -1


@njit(cache=True, parallel=True)
def _event_filter_kernel(xs, ys, ts, ps, width, height, t0, slot_us, guard_us, trans, threshold,
                         n_chunks, keep, period_out, slot_out, acc):  # pragma: no cover - numba
    n = ts.size
    L = trans.size
    period_us = slot_us * L
    tn = 0.0
    for j in range(L):
        tn += trans[j] * trans[j]
    tnorm = np.sqrt(tn)
    # period index per event (monotone because ts is sorted) and chunk split points on period edges
    starts = np.empty(n_chunks + 1, np.int64)
    starts[0] = 0
    starts[n_chunks] = n
    for c in range(1, n_chunks):
        i = (n * c) // n_chunks
        if i <= starts[c - 1]:
            i = starts[c - 1]
        else:
            pi = (ts[i] - t0 + guard_us) // period_us
            while i < n and (ts[i] - t0 + guard_us) // period_us == pi:
                i += 1
        starts[c] = i
    dropped = 0
    for c in prange(n_chunks):
        a = acc[c]
        lo = starts[c]
        hi = starts[c + 1]
        i = lo
        inv_slot = 1.0 / slot_us
        while i < hi:
            pcur = (ts[i] - t0 + guard_us) // period_us
            p_start = t0 - guard_us + pcur * period_us
            p_end = p_start + period_us
            j = i
            # pass 1: accumulate signed counts of this period
            while j < hi and ts[j] < p_end:
                x = np.int64(xs[j])
                y = np.int64(ys[j])
                rel = ts[j] - p_start
                sl = np.int64(rel * inv_slot)  # division-free slot, corrected for rounding
                if sl * slot_us > rel:
                    sl -= 1
                elif (sl + 1) * slot_us <= rel:
                    sl += 1
                period_out[j] = pcur
                slot_out[j] = sl
                if x < width and y < height:
                    a[(y * width + x) * L + sl] += 1 if ps[j] > 0 else -1
                j += 1
            # pass 2: decide per event
            for k in range(i, j):
                x = np.int64(xs[k])
                y = np.int64(ys[k])
                if x >= width or y >= height:
                    keep[k] = False
                    dropped += 1
                    continue
                base = (y * width + x) * L
                dot = 0.0
                nrm = 0.0
                for q in range(L):
                    v = np.float64(a[base + q])
                    dot += trans[q] * v
                    nrm += v * v
                sl = slot_out[k]
                sign = 1 if ps[k] > 0 else -1
                keep[k] = nrm > 0.0 and dot >= threshold * tnorm * np.sqrt(nrm) and trans[sl] * sign > 0
            # pass 3: reset the touched accumulators
            for k in range(i, j):
                x = np.int64(xs[k])
                y = np.int64(ys[k])
                if x < width and y < height:
                    base = (y * width + x) * L
                    for q in range(L):
                        a[base + q] = 0
            i = j
    return dropped


class _Workspace:
    """Per-thread accumulators reused across calls: int32 (chunks, H*W*L) signed event counts."""

    def __init__(self) -> None:
        self.key: tuple[int, int, int, int] | None = None
        self.acc: np.ndarray | None = None

    def get(self, chunks: int, width: int, height: int, length: int) -> np.ndarray:
        key = (chunks, width, height, length)
        if self.key != key or self.acc is None:
            self.acc = np.zeros((chunks, width * height * length), np.int32)
            self.key = key
        return self.acc


def _event_fields(events: np.ndarray):
    ev = np.asarray(events)
    if ev.dtype.names is None or not {"x", "y", "t", "p"} <= set(ev.dtype.names):
        raise ValueError(f"events must be a structured array with fields x, y, t, p (EVENT_DTYPE), got {ev.dtype}")
    if ev.ndim != 1:
        raise ValueError(f"events must be 1-D (N,), got shape {ev.shape}")
    return ev["x"], ev["y"], ev["t"].astype(np.int64, copy=False), ev["p"]


class EventMatchedFilter:
    """Streaming event matched filter: push time-ordered slices, get decisions for completed periods.

    code: the device's source code (L slots); slot_us: slot duration (microseconds, int);
    t0_us: time of the start of slot 0 of period 0 (the device's projector clock, plus sensor latency);
    guard_us: how far before a slot boundary an event may arrive and still count for that slot
    (default slot_us // 4: jitter is symmetric, latency only delays).
    Counts per pixel and slot are int32 (exact; see the module docstring for the memory); codes
    longer than `MAX_EVENT_CODE_LENGTH` slots are refused (ValueError).
    """

    def __init__(self, code: "SourceCode | str", *, width: int, height: int, slot_us: int,
                 t0_us: int = 0, guard_us: int | None = None, threshold: float = DEFAULT_EVENT_THRESHOLD,
                 threads: int | None = None) -> None:
        self.code = source_code(code)
        if self.code.length > MAX_EVENT_CODE_LENGTH:
            raise ValueError(f"the event filter takes codes of at most {MAX_EVENT_CODE_LENGTH} slots, got a code "
                             f"of {self.code.length} (its slot index is int16)")
        if width <= 0 or height <= 0:
            raise ValueError(f"sensor size must be positive, got {width}x{height}")
        if int(slot_us) < 1:
            raise ValueError(f"slot_us must be >= 1 microsecond, got {slot_us}")
        self.width, self.height = int(width), int(height)
        self.slot_us = int(slot_us)
        self.t0_us = int(t0_us)
        self.guard_us = self.slot_us // 4 if guard_us is None else int(guard_us)
        if not 0 <= self.guard_us < self.slot_us:
            raise ValueError(f"guard_us must be in [0, slot_us), got {self.guard_us}")
        if not -1.0 <= threshold <= 1.0:
            raise ValueError(f"threshold must be in [-1, 1] (a cosine), got {threshold}")
        self.threshold = float(threshold)
        self.chunks = int(threads or nb.get_num_threads())
        self._ws = _Workspace()
        self._pending = np.empty(0, EVENT_DTYPE)
        self._last_t: int | None = None
        self.dropped_out_of_bounds = 0
        self.events_in = 0

    @property
    def period_us(self) -> int:
        return self.slot_us * self.code.length

    def _period(self, t: np.ndarray) -> np.ndarray:
        return (t - self.t0_us + self.guard_us) // self.period_us

    def _run(self, events: np.ndarray) -> EventFilterResult:
        x, y, t, p = _event_fields(events)
        n = t.size
        keep = np.zeros(n, np.bool_)
        period = np.zeros(n, np.int64)
        slot = np.zeros(n, np.int16)  # L <= MAX_EVENT_CODE_LENGTH (int8 wrapped slots >= 128)
        if n:
            acc = self._ws.get(self.chunks, self.width, self.height, self.code.length)
            dropped = _event_filter_kernel(
                x, y, t, p, self.width, self.height, self.t0_us, self.slot_us, self.guard_us,
                self.code.transitions.astype(np.float64), self.threshold, min(self.chunks, max(1, n)),
                keep, period, slot, acc)
        else:
            dropped = 0
        self.dropped_out_of_bounds += int(dropped)
        return EventFilterResult(keep, period, slot, int(dropped))

    def push(self, events: np.ndarray) -> tuple[np.ndarray, EventFilterResult]:
        """Add a time slice; returns (events of the periods completed so far, their result).

        Raises ValueError when events go back in time (within the slice or against the last slice).
        Events of the last, possibly incomplete, period are held until the next push / `flush`.
        """
        ev = np.asarray(events)
        _event_fields(ev)
        check_events(ev)
        if ev.size and self._last_t is not None and int(ev["t"][0]) < self._last_t:
            raise ValueError(
                f"events out of time order: slice starts at t={int(ev['t'][0])} us, before the previous "
                f"slice's last event at t={self._last_t} us"
            )
        if ev.size:
            self._last_t = int(ev["t"][-1])
        self.events_in += int(ev.size)
        allev = np.concatenate([self._pending, ev.astype(EVENT_DTYPE, copy=False)]) if self._pending.size else ev
        if allev.size == 0:
            return allev, self._run(allev)
        last_period = self._period(np.int64(allev["t"][-1]))
        cut = int(np.searchsorted(self._period(allev["t"].astype(np.int64)), last_period, side="left"))
        done, self._pending = allev[:cut], allev[cut:].copy()
        return done, self._run(done)

    def flush(self) -> tuple[np.ndarray, EventFilterResult]:
        """Process the held (last) period."""
        ev, self._pending = self._pending, np.empty(0, EVENT_DTYPE)
        return ev, self._run(ev)


def filter_events(events: np.ndarray, code: "SourceCode | str", *, width: int, height: int, slot_us: int,
                  t0_us: int = 0, guard_us: int | None = None,
                  threshold: float = DEFAULT_EVENT_THRESHOLD) -> EventFilterResult:
    """Filter a whole time-ordered event array at once (see `EventMatchedFilter`)."""
    f = EventMatchedFilter(code, width=width, height=height, slot_us=slot_us, t0_us=t0_us,
                           guard_us=guard_us, threshold=threshold)
    _event_fields(events)
    check_events(np.asarray(events))
    return f._run(np.asarray(events))


def filter_events_numpy(events: np.ndarray, code: "SourceCode | str", *, width: int, height: int,
                        slot_us: int, t0_us: int = 0, guard_us: int | None = None,
                        threshold: float = DEFAULT_EVENT_THRESHOLD) -> np.ndarray:
    """Plain-numpy reference of `filter_events` (bool keep mask; the benchmark baseline)."""
    f = EventMatchedFilter(code, width=width, height=height, slot_us=slot_us, t0_us=t0_us,  # validates
                           guard_us=guard_us, threshold=threshold)
    code = f.code
    x, y, t, p = _event_fields(events)
    check_events(np.asarray(events))
    L = code.length
    guard = f.guard_us
    rel = t - t0_us + guard
    period = rel // (slot_us * L)
    slot = (rel - period * slot_us * L) // slot_us
    inb = (x.astype(np.int64) < width) & (y.astype(np.int64) < height)
    sign = np.where(p > 0, 1, -1)
    pix = (y.astype(np.int64) * width + x.astype(np.int64))
    key = (period - period.min(initial=0)) * (width * height) + pix
    ukey, inv = np.unique(key[inb], return_inverse=True)
    counts = np.zeros((ukey.size, L), np.float64)
    np.add.at(counts, (inv, slot[inb]), sign[inb])
    tr = code.transitions.astype(np.float64)
    dot = counts @ tr
    nrm = np.sqrt((counts**2).sum(axis=1))
    ok_pix = (nrm > 0) & (dot >= threshold * np.linalg.norm(tr) * nrm)
    keep = np.zeros(t.size, bool)
    keep[np.flatnonzero(inb)] = ok_pix[inv] & (tr[slot[inb]] * sign[inb] > 0)
    return keep
