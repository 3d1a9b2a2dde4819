"""Runtime building blocks: projector frame ids, stack assembly, drop-oldest queue, depth."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from edge.runtime.assembly import StackAssembler
from edge.runtime.depth import column_to_depth_mm, column_to_disparity, confidence_to_u8, disparity_to_depth_mm
from edge.runtime.stack_queue import Closed, LatestQueue
from edge.sensors.base import (BLACK, WHITE, Frame, SensorInfo, parse_projector_frame, projector_frame_id,
                               stack_schedule)


def test_projector_frame_ids_roundtrip_and_schedule():
    assert projector_frame_id(3) == 3
    pid = projector_frame_id(WHITE, slot=2, edc_round=1)
    assert parse_projector_frame(pid) == (WHITE, 2, 1)
    assert parse_projector_frame(pid).is_white and parse_projector_frame(BLACK).is_black
    assert parse_projector_frame(5).code_index == 5 and parse_projector_frame(WHITE).code_index == -1
    s = stack_schedule(3)
    assert s.tolist() == [0, 1, 2, WHITE, BLACK]
    s2 = stack_schedule(2, 2)
    assert [tuple(parse_projector_frame(i)[:2]) for i in s2] == [(0, 0), (0, 1), (1, 0), (1, 1), (WHITE, 0), (WHITE, 1), (BLACK, 0), (BLACK, 1)]
    assert SensorInfo("x", 4, 3, 8, 0.0, 3, 2).frames_per_stack == 10
    with pytest.raises(ValueError, match="slot"):
        projector_frame_id(0, slot=300)
    with pytest.raises(ValueError, match="code frames"):
        stack_schedule(0)


def _frames(schedule, stack, seq0, value=None):
    return [Frame(np.full((2, 3), stack if value is None else value, np.uint8), seq0 + i, 1000 * (seq0 + i), 100.0, int(p), stack)
            for i, p in enumerate(schedule)]


def test_assembly_complete_stacks():
    sched = stack_schedule(3)
    asm = StackAssembler(sched)
    out = [s for f in _frames(sched, 0, 0) + _frames(sched, 1, 5) if (s := asm.push(f))]
    assert [s.stack for s in out] == [0, 1]
    assert out[1].first_sequence == 5 and out[1].timestamp_ns == 9000
    assert out[0].images().shape == (5, 2, 3)
    assert asm.counters.stacks_complete == 2 and asm.counters.stacks_incomplete == 0


def test_assembly_flush_at_stop_counts_cut_stack_not_incomplete():
    sched = stack_schedule(3)
    frames = _frames(sched, 0, 0) + _frames(sched, 1, 5)[:2]
    asm = StackAssembler(sched)
    for f in frames:
        asm.push(f)
    asm.flush(stopping=True)  # the service stopped while stack 1 was being captured
    assert asm.counters.stacks_cut_at_stop == 1 and asm.counters.stacks_incomplete == 0
    asm = StackAssembler(sched)
    for f in frames:
        asm.push(f)
    asm.flush()  # end of a recording: a partial stack is an incomplete one
    assert asm.counters.stacks_cut_at_stop == 0 and asm.counters.stacks_incomplete == 1


def test_assembly_sequence_gap_drops_stack_and_counts():
    sched = stack_schedule(3)
    asm = StackAssembler(sched)
    frames = _frames(sched, 0, 0) + _frames(sched, 1, 5) + _frames(sched, 2, 10)
    del frames[7]  # lose frame 2 of stack 1
    out = [s for f in frames if (s := asm.push(f))]
    assert [s.stack for s in out] == [0, 2]
    assert asm.counters.sequence_gaps == 1 and asm.counters.stacks_incomplete == 1
    # every emitted stack holds only its own frames
    for s in out:
        assert all(f.stack == s.stack and int(f.image[0, 0]) == s.stack for f in s.frames)


def test_assembly_out_of_order_drops_stack_and_counts():
    sched = stack_schedule(3)
    asm = StackAssembler(sched)
    frames = _frames(sched, 0, 0) + _frames(sched, 1, 5) + _frames(sched, 2, 10)
    frames[6], frames[7] = frames[7], frames[6]  # swap two frames of stack 1
    out = [s for f in frames if (s := asm.push(f))]
    assert [s.stack for s in out] == [0, 2]
    assert asm.counters.out_of_order == 1 and asm.counters.stacks_incomplete == 1


def test_assembly_lost_first_frame_and_truncated_tail():
    sched = stack_schedule(2)
    asm = StackAssembler(sched)
    frames = _frames(sched, 0, 0) + _frames(sched, 1, 4)
    frames = frames[1:] + _frames(sched, 2, 8)[:2]  # stack 0 misses its first frame, stack 2 its tail
    out = [s for f in frames if (s := asm.push(f))]
    assert [s.stack for s in out] == [1]
    asm.flush()
    assert asm.counters.stacks_incomplete == 2


def test_assembly_rejects_wrong_projector_frame():
    sched = stack_schedule(2)
    asm = StackAssembler(sched)
    frames = _frames(sched, 0, 0)
    frames[1] = Frame(frames[1].image, 1, 0, 1.0, WHITE, 0)  # white where code frame 1 belongs
    assert not [s for f in frames if (s := asm.push(f))]
    asm.flush()
    assert asm.counters.unexpected_frames == 1 and asm.counters.stacks_incomplete == 1


def test_assembly_hook_sees_every_accepted_frame_at_its_position():
    """on_frame(index, frame) is called for each accepted frame with its stack position; a
    returned Stack holds exactly the frames passed for positions 0..m-1 since the last index 0;
    a broken stack gets no more calls (its staged frames are never completed)."""
    sched = stack_schedule(3)
    calls = []
    asm = StackAssembler(sched, on_frame=lambda i, f: calls.append((i, f)))
    f0 = _frames(sched, 0, 0)
    f1 = _frames(sched, 1, 5)
    f2 = _frames(sched, 2, 10)
    done = [asm.push(f) for f in f0[:2]]  # stack 0 loses frame 2
    done += [asm.push(f) for f in f0[3:]]
    assert calls == [(0, f0[0]), (1, f0[1])]  # frames after the gap are not accepted
    out = [asm.push(f) for f in f1] + [asm.push(f) for f in f2]
    stacks = [s for s in done + out if s is not None]
    assert [s.stack for s in stacks] == [1, 2]
    for s in stacks:
        since = calls[max(i for i, (pos, f) in enumerate(calls) if pos == 0 and f.stack == s.stack):]
        assert [pos for pos, _ in since][: len(sched)] == list(range(len(sched)))
        assert all(a is b for (_, a), b in zip(since, s.frames))
    assert len(calls) == 2 + 2 * len(sched)


def test_cpu_backend_has_no_capture_hook_and_imports_no_cuda():
    """The CPU path is unchanged: the pipeline has no on_frame hook, the service's assembler calls
    nothing per frame, and no CUDA module is imported (checked in a fresh interpreter)."""
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    script = r"""
import sys
sys.path.insert(0, "tests")
from _service_helpers import load_test_profile
from edge.runtime.pipeline import DepthPipeline
p = DepthPipeline(load_test_profile())
assert p.on_frame is None and p.stager is None, p.on_frame
bad = sorted(m for m in sys.modules if m.startswith(("edge.decode.backends.cuda", "numba.cuda", "numba_cuda")))
assert not bad, bad
print("OK")
"""
    proc = subprocess.run([sys.executable, "-c", script], cwd=root, capture_output=True, text=True, timeout=300,
                          env={**__import__("os").environ, "PYTHONPATH": str(root)})
    assert proc.returncode == 0 and "OK" in proc.stdout, proc.stderr[-2000:]


def test_latest_queue_drops_oldest_and_never_blocks():
    q: LatestQueue[int] = LatestQueue(2)
    assert q.put(1) is None and q.put(2) is None
    assert q.put(3) == 1 and q.dropped == 1
    assert q.get(0) == 2 and q.get(0) == 3 and q.get(0.01) is None
    q.put(4)
    q.close()
    assert q.get(0) == 4
    with pytest.raises(Closed):
        q.get(0)
    with pytest.raises(ValueError, match="capacity"):
        LatestQueue(0)


def _queue_with_wait_signal(capacity: int):
    """A LatestQueue whose condition sets the returned Event when a getter starts waiting."""
    waiting = threading.Event()

    class Watched(threading.Condition):
        def wait(self, timeout=None):
            waiting.set()
            return super().wait(timeout)

    q: LatestQueue[int] = LatestQueue(capacity)
    q._cond = Watched()
    return q, waiting


def test_latest_queue_wakes_waiting_getter():
    """A getter already blocked in get() returns as soon as an item is put, long before its
    timeout (without the wait signal the put could come first, and an unwoken getter still
    returned the item at its timeout: the test could not tell)."""
    import time

    q, waiting = _queue_with_wait_signal(1)
    got = []
    t = threading.Thread(target=lambda: got.append((q.get(60), time.monotonic())), daemon=True)
    t.start()
    assert waiting.wait(10), "the getter never waited"
    put_at = time.monotonic()
    q.put(7)
    t.join(30)
    assert not t.is_alive() and len(got) == 1
    item, returned_at = got[0]
    assert item == 7 and returned_at - put_at < 10  # woken by put, not by the 60 s timeout


def test_latest_queue_close_wakes_waiting_getter():
    """close() wakes a blocked getter, which raises Closed (the service's decode thread exits)."""
    q, waiting = _queue_with_wait_signal(1)
    raised = []

    def get():
        try:
            q.get(60)
        except Closed:
            raised.append(True)

    t = threading.Thread(target=get, daemon=True)
    t.start()
    assert waiting.wait(10), "the getter never waited"
    q.close()
    t.join(30)
    assert not t.is_alive() and raised == [True]


class G:
    focal_px = 560.0
    baseline_m = 0.08
    cx_camera = 320.0
    cx_projector = 512.0


def test_depth_from_column_matches_formula():
    column = np.array([[100, 200, -1, 639], [0, 511, 300, 320]], dtype=np.int32)
    depth = column_to_depth_mm(column, G())
    x = np.arange(4)[None, :]
    d = x - column
    expected = np.rint(560.0 * 0.08 * 1000.0 / (d + 192.0))
    ok = (column >= 0) & (d + 192 > 0) & (expected <= 65535)
    assert depth.dtype == np.uint16
    assert np.array_equal(depth[ok], expected[ok].astype(np.uint16))
    assert np.all(depth[~ok] == 0)
    assert depth[0, 2] == 0  # invalid column
    assert depth[1, 1] == 0  # d + doffs = 1 - 511 + 192 <= 0


def test_depth_invalid_cases_and_stripe():
    disp = np.array([[np.nan, -192.0, -191.9999, 1e9]])
    assert disparity_to_depth_mm(disp, G()).tolist() == [[0, 0, 0, 0]]
    col = np.array([[10]], dtype=np.int32)
    # stripe 4: codeword 10 covers projector columns 40..43, centre 41.5
    assert column_to_depth_mm(col, G(), stripe=4)[0, 0] == np.uint16(np.rint(44800.0 / (0 - 41.5 + 192)))
    assert np.isnan(column_to_disparity(np.array([[-1, 2]], np.int32))[0, 0])
    with pytest.raises(ValueError, match="2-D"):
        column_to_depth_mm(np.zeros(4, np.int32), G())


def test_depth_matches_formula_on_random_columns_and_stripes():
    # Independent float64 evaluation of Z = f * b / (x - (col + 0.5) * stripe + 0.5 ... ) per
    # docs/architecture.md: the centre of codeword col is projector column (col + 0.5) * stripe - 0.5.
    rng = np.random.default_rng(1)
    col = rng.integers(-1, 1024, size=(48, 64)).astype(np.int32)
    x = np.arange(64, dtype=np.float64)[None, :]
    for stripe in (1, 2, 4):
        centre = (col + 0.5) * stripe - 0.5
        d = x - centre
        with np.errstate(divide="ignore", invalid="ignore"):
            expected = np.rint(560.0 * 0.08 * 1000.0 / (d + 192.0))
        ok = (col >= 0) & (d + 192.0 > 0) & (expected <= 65535) & (expected >= 1)
        depth = column_to_depth_mm(col, G(), stripe=stripe)
        assert np.array_equal(depth[ok], expected[ok].astype(np.uint16)), stripe
        assert np.all(depth[~ok] == 0), stripe
        assert ok.sum() > 100


def test_confidence_to_u8():
    c = np.array([[0.0, 0.5, 1.0, np.nan, 2.0]], dtype=np.float32)
    assert confidence_to_u8(c).tolist() == [[0, 128, 255, 0, 255]]
    # 0 means invalid on the wire: a valid pixel gets at least 1, however low its confidence
    assert confidence_to_u8(c, np.array([[1, 0, 1, 1, 1]], bool)).tolist() == [[1, 0, 255, 1, 255]]
    low = np.array([[0.001, 0.001]], np.float32)
    assert confidence_to_u8(low).tolist() == [[0, 0]]
    assert confidence_to_u8(low, np.array([[True, False]])).tolist() == [[1, 0]]
