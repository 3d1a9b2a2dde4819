"""Room source-code families: fractional offsets reduce to integer shifts, the sum bound is exact."""

from __future__ import annotations

import numpy as np
import pytest

from edge.codes.source import source_code
from edge.codes.source_room import (bound_matrices, foreign_windows, guarantee, margin_table, response_bounds,
                                    room_family, tdm_row, uncoded_row)


def _dense_frame_windows(foreign, length, sub=16, stream="aperiodic", rng=None):
    """Independent model: the foreign stream sampled at 1/sub slot, shifted by every sub-step and
    box-integrated over my slots (periodic: code repeated; aperiodic: random on/off symbols)."""
    rng = rng or np.random.default_rng(0)
    fl = foreign.length
    out = []
    n_streams = 1 if stream == "periodic" else 24
    for _ in range(n_streams):
        nsym = length // fl + 4
        states = np.ones(nsym) if stream == "periodic" else rng.integers(0, 2, nsym)
        x = np.concatenate([foreign.bits * s for s in states]).astype(float)
        fine = np.repeat(x, sub)
        for k in range(fl * sub):
            seg = fine[fl * sub + k: fl * sub + k + length * sub]
            out.append(seg.reshape(length, sub).mean(axis=1))
    return np.array(out)


def _dense_event_windows(foreign, length, sub=16, rng=None):
    rng = rng or np.random.default_rng(1)
    fl = foreign.length
    out = []
    for _ in range(24):
        states = rng.integers(0, 2, length // fl + 4)
        x = np.concatenate([foreign.bits * s for s in states]).astype(float)
        edges = np.diff(x)  # edge e at time e + 1 (foreign slots)
        times = np.arange(1, edges.size + 1, dtype=float)
        for k in range(fl * sub):
            t = times - fl - k / sub  # my clock: window starts at 0
            win = np.zeros(length)
            ok = (t >= 0) & (t < length) & (edges != 0)
            np.add.at(win, np.floor(t[ok]).astype(int), edges[ok])
            out.append(win)
    return np.array(out)


@pytest.mark.parametrize("mine,foreign", [("00110101", "00100111"), ("1100", "0101"), ("0010111", "0011011")])
def test_fractional_offsets_never_exceed_the_integer_shift_bounds(mine, foreign):
    a, b = source_code(mine), source_code(foreign)
    for stream in ("aperiodic", "periodic"):
        if stream == "periodic" and a.length != b.length:
            continue
        hi, lo = response_bounds(a, b, stream=stream)
        dense = _dense_frame_windows(b, a.length, stream=stream)
        r = dense @ a.template / (a.template @ a.template)
        assert r.max() <= hi + 1e-9 and r.min() >= lo - 1e-9
        assert r.max() == pytest.approx(hi, abs=1e-9) or stream == "aperiodic"  # integer shifts are in the dense set
        ints = foreign_windows(b, a.length, stream=stream) @ a.template / (a.template @ a.template)
        assert ints.max() == pytest.approx(hi) and ints.min() == pytest.approx(lo)
    tr = a.transitions.astype(float)
    hi, lo = response_bounds(a, b, kind="event")
    r = _dense_event_windows(b, a.length) @ tr / (tr @ tr)
    assert r.max() <= hi + 1e-9 and r.min() >= lo - 1e-9


def test_sum_of_foreign_devices_stays_inside_the_exact_bound_and_reaches_it():
    fam = room_family(4, 8, "frame", "periodic")
    assert len({c.string for c in fam}) == 4
    g = guarantee(fam, stream="periodic")
    bp, bm = bound_matrices(fam, stream="periodic")
    rng = np.random.default_rng(3)
    me, others = fam[0], fam[1:]
    s = me.template / (me.template @ me.template)
    dense = [_dense_frame_windows(o, 8, stream="periodic") for o in others]
    worst_hi, worst_lo = -np.inf, np.inf
    for _ in range(3000):
        total = sum(rng.uniform(0, 1) * d[rng.integers(len(d))] for d in dense)
        v = float(total @ s)
        worst_hi, worst_lo = max(worst_hi, v), min(worst_lo, v)
    assert worst_hi <= g.false_bound[0] + 1e-9
    assert 1 + worst_lo >= g.own_bound[0] - 1e-9
    # attained: every device at full power at its own worst integer shift
    best = sum((foreign_windows(o, 8, stream="periodic") @ s).max() for o in others)
    assert best == pytest.approx(bp[0].sum())
    assert g.margin[0] == pytest.approx(1 - bp[0].sum() - bm[0].sum())


def test_margin_table_rows_and_anchors():
    assert uncoded_row(3).margin == pytest.approx(-1.0) and uncoded_row(1).margin == 1.0
    assert tdm_row(5).frame_cost == 5 and tdm_row(5).needs_sync
    rows = margin_table(ns=(2, 3), lengths=(4, 8), stream="periodic")
    coded = {(r.n_devices, r.length): r for r in rows if r.scheme == "source codes"}
    assert coded[(2, 8)].margin > 0 and coded[(2, 8)].max_power_ratio > 1
    assert (3, 4) in coded and coded[(3, 4)].margin < 0  # three L=4 codes cannot be separated
    with pytest.raises(ValueError, match="only 3 usable codes"):
        room_family(4, 4)
