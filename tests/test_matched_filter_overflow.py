"""Event matched filter: counts past int16 in one pixel's slot, and codes longer than its slot index.

The per-thread accumulators held signed event counts per pixel and slot in int16: more than 32,767
events of one polarity in one pixel's slot wrapped negative, the cosine with the code's transitions
flipped sign and every own event of that pixel was dropped.  The events here come from the DVS
simulator (`simulate_events`) and are checked against a count made with ``np.add.at``.
"""

from __future__ import annotations

import numpy as np
import pytest

from edge.codes.source import source_code
from edge.source.events import EventSensor, event_slices, simulate_events
from edge.source.matched_filter import MAX_EVENT_CODE_LENGTH, EventMatchedFilter, filter_events

CODE = "10100010"
SLOT_US = 1000
#: log-intensity step of pixel 0 over a contrast threshold of 0.01: about 35,000 events per edge
HUGE_STEP = 350.0


def _hot_pixel_events() -> tuple[np.ndarray, int, int]:
    """(events, width, height): two periods of CODE on a 2 x 1 sensor, pixel 0 with edges of about
    35,000 events each (no refractory time, latency, jitter or background), pixel 1 with a few."""
    code = source_code(CODE)
    periods = 2
    bits = np.tile(code.bits, periods).astype(np.float64)
    inten = np.empty((bits.size + 1, 1, 2))
    inten[0] = 1.0                                                   # pre-roll slot: off
    inten[1:, 0, 0] = np.exp(HUGE_STEP * bits)
    inten[1:, 0, 1] = 1.0 + 3.0 * bits
    times = np.arange(-1, bits.size, dtype=np.int64) * SLOT_US
    sensor = EventSensor(2, 1, contrast_pos=0.01, contrast_neg=0.01, threshold_sigma=0.0, refractory_us=0,
                         latency_us=0, jitter_us=0.0, background_rate_hz=0.0)
    ev = simulate_events(inten, times, sensor, rng=np.random.default_rng(3), end_us=bits.size * SLOT_US)
    return ev, 2, 1


def _reference_keep(ev: np.ndarray, width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
    """(keep (N,) bool, counts int64 (periods, H*W, L)) by the filter's rule, counted with np.add.at."""
    code = source_code(CODE)
    L = code.length
    guard = SLOT_US // 4
    rel = ev["t"].astype(np.int64) + guard
    period = rel // (SLOT_US * L)
    slot = (rel - period * SLOT_US * L) // SLOT_US
    pix = ev["y"].astype(np.int64) * width + ev["x"].astype(np.int64)
    sign = np.where(ev["p"] > 0, 1, -1)
    counts = np.zeros((int(period.max()) + 1, width * height, L), np.int64)
    np.add.at(counts, (period, pix, slot), sign)
    tr = code.transitions.astype(np.float64)
    c = counts[period, pix].astype(np.float64)
    cos = (c @ tr) / (np.linalg.norm(tr) * np.maximum(np.linalg.norm(c, axis=1), 1e-300))
    keep = (np.linalg.norm(c, axis=1) > 0) & (cos >= 0.92) & (tr[slot] * sign > 0)
    return keep, counts


def test_more_than_32767_events_in_one_pixel_slot_match_the_np_add_at_reference():
    ev, w, h = _hot_pixel_events()
    keep, counts = _reference_keep(ev, w, h)
    assert np.abs(counts[:, 0]).max() > 32767          # the hot pixel's edges overflow int16
    assert 0 < np.abs(counts[:, 1]).max() < 1000   # pixel 1: an ordinary pixel (log 4 / 0.01 events)
    assert keep[(ev["x"] == 0)].all()                  # its counts are exactly the code's edges
    res = filter_events(ev, CODE, width=w, height=h, slot_us=SLOT_US)
    np.testing.assert_array_equal(res.keep, keep)


def test_streaming_filter_keeps_the_hot_pixel_across_pushes():
    """The accumulators are reused between pushes: each period is counted from zero again."""
    ev, w, h = _hot_pixel_events()
    keep, _ = _reference_keep(ev, w, h)
    f = EventMatchedFilter(CODE, width=w, height=h, slot_us=SLOT_US, threads=2)
    got = []
    for part in event_slices(ev, 3 * SLOT_US, start_us=-SLOT_US):
        done, r = f.push(part)
        got.append(r.keep)
    got.append(f.flush()[1].keep)
    np.testing.assert_array_equal(np.concatenate(got), keep)


def test_codes_longer_than_the_slot_index_are_refused():
    """Slots are int16: a code of more than 32,768 slots would wrap its late slots negative."""
    assert MAX_EVENT_CODE_LENGTH == 32768
    EventMatchedFilter("1" + "0" * (MAX_EVENT_CODE_LENGTH - 1), width=1, height=1, slot_us=1)
    too_long = "1" + "0" * MAX_EVENT_CODE_LENGTH
    with pytest.raises(ValueError, match=r"at most 32768 slots, got a code of 32769"):
        EventMatchedFilter(too_long, width=1, height=1, slot_us=1)
    with pytest.raises(ValueError, match=r"at most 32768 slots"):
        filter_events(np.empty(0, dtype=[("x", "<u2"), ("y", "<u2"), ("t", "<i8"), ("p", "i1")]), too_long,
                      width=1, height=1, slot_us=1)
