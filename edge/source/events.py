"""Event-sensor simulator (DVS model) and event-array helpers.

Events are a numpy structured array of `EVENT_DTYPE`: ``x`` u2, ``y`` u2 (pixel), ``t`` i8
(microseconds), ``p`` i1 (+1 brighter, -1 darker), sorted by ``t``.

Model (per pixel, `simulate_events`): the input is a piecewise-constant intensity: frame i holds from
``times_us[i]`` until ``times_us[i+1]`` (the last one until ``end_us``).  The pixel keeps a reference
log intensity; whenever ``log(I + eps) - ref >= C+`` it emits a positive event and moves ``ref`` up by
C+ (negative likewise with C-), so a step of n thresholds gives n events.  After each event the pixel
is blind for ``refractory_us``; a change still pending fires when the refractory period ends (if the
intensity has not moved on).  Per-pixel thresholds vary (``threshold_sigma``, fixed pattern noise),
events are delayed by ``latency_us`` and jittered by Gaussian ``jitter_us``, and background activity
adds Poisson events of random polarity at ``background_rate_hz`` per pixel.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Iterator

import numpy as np
from numba import njit, prange

from ..numba_cache import install as _install_cache_lock

_install_cache_lock()  # before any kernel of this module is compiled or loaded (edge.numba_cache)

EVENT_DTYPE = np.dtype([("x", "<u2"), ("y", "<u2"), ("t", "<i8"), ("p", "i1")])

#: Source labels returned by `simulate_events(..., labels=...)` for background-activity events.
LABEL_BACKGROUND = 128


def check_events(events: np.ndarray) -> None:
    """Raise ValueError unless ``events`` is time-ordered (non-decreasing ``t``)."""
    from .matched_filter import _first_unsorted

    ev = np.asarray(events)
    if ev.dtype.names is None or "t" not in ev.dtype.names:
        raise ValueError(f"events must be a structured array with a t field (EVENT_DTYPE), got {ev.dtype}")
    t = ev["t"].astype(np.int64, copy=False)
    if t.size > 1:
        bad = int(_first_unsorted(t))
        if bad >= 0:
            raise ValueError(
                f"events out of time order: event {bad} has t={int(t[bad])} us after t={int(t[bad - 1])} us; "
                "sort by t first"
            )


def make_events(x, y, t, p) -> np.ndarray:
    """Structured event array (`EVENT_DTYPE`) from equal-length 1-D x, y (integer pixels,
    0..65535), t (integer us) and p (> 0: +1, else -1) arrays; not sorted.  ValueError names
    the field that does not fit (lengths, non-integer values, coordinates outside uint16) rather
    than wrapping it."""
    x, y, t, p = (np.asarray(v) for v in (x, y, t, p))
    if not (x.ndim == y.ndim == t.ndim == p.ndim == 1 and x.size == y.size == t.size == p.size):
        raise ValueError(f"events: x, y, t, p must be 1-D arrays of one length, got shapes "
                         f"{x.shape}, {y.shape}, {t.shape}, {p.shape}")
    for name, v, hi in (("x", x, 65535), ("y", y, 65535), ("t", t, None)):
        if not v.size:
            continue
        integral = (np.issubdtype(v.dtype, np.integer) or np.issubdtype(v.dtype, np.bool_)
                    or (np.issubdtype(v.dtype, np.floating) and np.isfinite(v).all() and (v == np.round(v)).all()))
        if not integral:
            raise ValueError(f"events: {name} must hold integers, got {v.dtype} values such as {v.ravel()[0]!r}")
        if hi is not None and (v.min() < 0 or v.max() > hi):
            raise ValueError(f"events: {name} must lie in 0..{hi} (uint16 pixels), got {v.min()}..{v.max()}")
    ev = np.empty(t.size, EVENT_DTYPE)
    ev["x"], ev["y"], ev["t"], ev["p"] = x, y, t, np.where(p > 0, 1, -1)
    return ev


@dataclass(frozen=True)
class EventSensor:
    """DVS parameters (defaults loosely after a 640x480 Prophesee-class sensor; times in us)."""

    width: int
    height: int
    contrast_pos: float = 0.25
    contrast_neg: float = 0.25
    threshold_sigma: float = 0.02
    refractory_us: int = 20
    latency_us: int = 50
    jitter_us: float = 15.0
    background_rate_hz: float = 0.2
    eps: float = 1e-3

    def __post_init__(self) -> None:
        if self.width <= 0 or self.height <= 0:
            raise ValueError(f"sensor size must be positive, got {self.width}x{self.height}")
        if self.contrast_pos <= 0 or self.contrast_neg <= 0:
            raise ValueError(f"contrast thresholds must be > 0, got {self.contrast_pos}, {self.contrast_neg}")
        if self.refractory_us < 0 or self.jitter_us < 0 or self.background_rate_hz < 0:
            raise ValueError("refractory_us, jitter_us and background_rate_hz must be >= 0")


@njit(cache=True, parallel=True)
def _dvs_kernel(logi, times, end_us, cpos, cneg, refractory, step_labels, count_only, counts, offsets,
                out_x, out_y, out_t, out_p, out_label):  # pragma: no cover - numba
    T, h, w = logi.shape
    for y in prange(h):
        k = offsets[y]
        n_row = 0
        for x in range(w):
            ref = logi[0, y, x]
            ready = times[0]
            label = 0
            cp = cpos[y, x]
            cn = cneg[y, x]
            for i in range(T):
                level = logi[i, y, x]
                if i > 0 and level != logi[i - 1, y, x]:
                    label = step_labels[i]
                t_hi = end_us if i + 1 == T else times[i + 1]
                t = times[i] if times[i] > ready else ready
                while t < t_hi:
                    d = level - ref
                    if d >= cp:
                        pol = 1
                        ref += cp
                    elif -d >= cn:
                        pol = -1
                        ref -= cn
                    else:
                        break
                    if not count_only:
                        out_x[k] = x
                        out_y[k] = y
                        out_t[k] = t
                        out_p[k] = pol
                        out_label[k] = label
                        k += 1
                    n_row += 1
                    ready = t + refractory
                    t = ready if refractory > 0 else t
                # a change left pending keeps waiting for the next frame's level
        counts[y] = n_row


def simulate_events(
    intensity: np.ndarray,
    times_us: np.ndarray,
    sensor: EventSensor,
    *,
    rng: np.random.Generator,
    end_us: int | None = None,
    step_labels: np.ndarray | None = None,
    return_labels: bool = False,
):
    """Events a DVS sees from a piecewise-constant intensity sequence.

    intensity: float (T, H, W) linear intensity >= 0 (any scale; the log uses ``+ eps``).
    times_us: int64 (T,) strictly increasing start time of each frame (us).
    end_us: end of the last frame (default: last time + the median frame duration).
    step_labels: optional uint8 (T,) label of what changed at each frame start (bit mask, caller's
        meaning); an event is labelled with the label of the last frame at which its pixel's level
        changed, background events with `LABEL_BACKGROUND`.
    Returns events (EVENT_DTYPE, sorted by t), and with ``return_labels`` also uint8 (N,) labels.
    """
    inten = np.asarray(intensity, dtype=np.float64)
    if inten.ndim != 3 or inten.shape[1:] != (sensor.height, sensor.width):
        raise ValueError(f"intensity must be (T, {sensor.height}, {sensor.width}), got shape {inten.shape}")
    times = np.asarray(times_us, dtype=np.int64)
    if times.shape != (inten.shape[0],):
        raise ValueError(f"times_us must be ({inten.shape[0]},), got shape {times.shape}")
    if times.size == 0:
        raise ValueError("intensity must hold at least one frame, got T = 0")
    if times.size > 1 and np.any(np.diff(times) <= 0):
        raise ValueError("times_us must be strictly increasing")
    if end_us is None:
        end_us = int(times[-1] + (np.median(np.diff(times)) if times.size > 1 else 1000))
    if int(end_us) <= int(times[-1]):
        raise ValueError(f"end_us must be after the last frame's start {int(times[-1])} us, got {end_us}")
    labels_in = np.zeros(times.size, np.uint8) if step_labels is None else np.asarray(step_labels, np.uint8)
    logi = np.log(np.maximum(inten, 0.0) + sensor.eps)
    h, w = sensor.height, sensor.width
    cpos = np.maximum(sensor.contrast_pos + sensor.threshold_sigma * rng.standard_normal((h, w)), 0.01)
    cneg = np.maximum(sensor.contrast_neg + sensor.threshold_sigma * rng.standard_normal((h, w)), 0.01)
    counts = np.zeros(h, np.int64)
    offsets = np.zeros(h, np.int64)
    dummy = np.zeros(0, np.int64)
    _dvs_kernel(logi, times, int(end_us), cpos, cneg, int(sensor.refractory_us), labels_in, True, counts,
                offsets, dummy.astype(np.uint16), dummy.astype(np.uint16), dummy, dummy.astype(np.int8),
                dummy.astype(np.uint8))
    offsets[1:] = np.cumsum(counts)[:-1]
    n = int(counts.sum())
    ox, oy = np.empty(n, np.uint16), np.empty(n, np.uint16)
    ot, op, ol = np.empty(n, np.int64), np.empty(n, np.int8), np.empty(n, np.uint8)
    _dvs_kernel(logi, times, int(end_us), cpos, cneg, int(sensor.refractory_us), labels_in, False, counts,
                offsets, ox, oy, ot, op, ol)
    ot = ot + int(sensor.latency_us)
    if sensor.jitter_us > 0:
        ot = ot + np.rint(sensor.jitter_us * rng.standard_normal(n)).astype(np.int64)
    # background activity: Poisson per pixel over [times[0], end_us)
    duration_s = (int(end_us) - int(times[0])) * 1e-6
    nb_ = int(rng.poisson(sensor.background_rate_hz * duration_s * h * w))
    bx = rng.integers(0, w, nb_).astype(np.uint16)
    by = rng.integers(0, h, nb_).astype(np.uint16)
    bt = rng.integers(int(times[0]), int(end_us), nb_).astype(np.int64)
    bp = np.where(rng.random(nb_) < 0.5, 1, -1).astype(np.int8)
    ev = make_events(np.concatenate([ox, bx]), np.concatenate([oy, by]), np.concatenate([ot, bt]),
                     np.concatenate([op, bp]))
    lab = np.concatenate([ol, np.full(nb_, LABEL_BACKGROUND, np.uint8)])
    order = np.argsort(ev["t"], kind="stable")
    ev, lab = ev[order], lab[order]
    return (ev, lab) if return_labels else ev


def event_slices(events: np.ndarray, slice_us: int, *, start_us: int | None = None) -> Iterator[np.ndarray]:
    """Yield consecutive time slices [start + k*slice_us, start + (k+1)*slice_us) of a time-ordered
    event array (views; empty slices are yielded too, so the caller's clock keeps running).
    start_us: the first slice's start (default the first event's time), at or before the first
    event (ValueError otherwise: the events before it would fall in no slice)."""
    if slice_us < 1:
        raise ValueError(f"slice_us must be >= 1, got {slice_us}")
    check_events(events)
    if events.size == 0:
        return
    t = events["t"]
    start = int(t[0]) if start_us is None else int(start_us)
    if start > int(t[0]):
        raise ValueError(f"start_us {start} is after the first event (t = {int(t[0])} us): the events before it "
                         f"would be in no slice; slice the array first to leave them out")
    edges = np.arange(start, int(t[-1]) + slice_us + 1, slice_us, dtype=np.int64)
    idx = np.searchsorted(t, edges, side="left")
    for a, b in zip(idx[:-1], idx[1:]):
        yield events[a:b]


def event_frame(events: np.ndarray, width: int, height: int, *, polarity: int | None = None,
                mask: np.ndarray | None = None) -> np.ndarray:
    """Count events per pixel: int32 (H, W).  polarity +1 / -1 keeps only that polarity; mask selects
    events (bool (N,)).  Events outside the sensor are ignored."""
    ev = events if mask is None else events[mask]
    if polarity is not None:
        ev = ev[ev["p"] == polarity]
    x = ev["x"].astype(np.int64)
    y = ev["y"].astype(np.int64)
    ok = (x < width) & (y < height)
    img = np.zeros(height * width, np.int32)
    np.add.at(img, y[ok] * width + x[ok], 1)
    return img.reshape(height, width)
