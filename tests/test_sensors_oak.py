"""OAK backend without a device: host-side depthai pipeline through the real conversion path."""

from __future__ import annotations

import datetime
import time

import numpy as np
import pytest

dai = pytest.importorskip("depthai")

from edge.profiles import apply_update, load_profile  # noqa: E402
from edge.runtime.assembly import StackAssembler  # noqa: E402
from edge.sensors.base import BLACK, WHITE, parse_projector_frame, stack_schedule  # noqa: E402
from edge.sensors.oak import (EmitterSchedule, OakSensor, RecordingEmitter, StackNumbering,  # noqa: E402
                              frame_from_imgframe, timedelta_ns)

W, H = 16, 12


def _img(i: int) -> np.ndarray:
    return ((np.arange(H * W).reshape(H, W) + 7 * i) % 251).astype(np.uint8)


class FakeMono(dai.node.ThreadedHostNode):
    """Sends GRAY8 ImgFrames with given sequence numbers, like a mono camera would."""

    sequences: list[int] = []

    def __init__(self):
        super().__init__()
        self.out = self.createOutput()

    def run(self):
        for i, seq in enumerate(self.sequences):
            f = dai.ImgFrame()
            f.setType(dai.ImgFrame.Type.GRAY8)
            f.setWidth(W)
            f.setHeight(H)
            f.setData(_img(seq).reshape(-1))
            f.setSequenceNum(seq)
            f.setTimestamp(datetime.timedelta(microseconds=1000 * seq))
            f.setTimestampDevice(datetime.timedelta(microseconds=1000 * seq))
            self.out.send(f)
            time.sleep(0.002)


def test_emitter_schedule_follows_source_code():
    sched = stack_schedule(2, 4)
    e = EmitterSchedule(sched, "1101", dot_intensity=0.5, flood_intensity=0.3)
    dots = [e.intensities(p)[0] for p in range(len(sched))]
    # code frames 0, 1 and WHITE follow 1101; BLACK keeps the projector off
    assert dots == [0.5, 0.5, 0.0, 0.5] * 3 + [0.0] * 4
    assert [e.intensities(p)[1] for p in range(8, 12)] == [0.3, 0.3, 0.0, 0.3]
    with pytest.raises(ValueError, match="dot_intensity"):
        EmitterSchedule(sched, "1101", dot_intensity=2.0)


def test_stack_numbering_from_sequence():
    n = StackNumbering(stack_schedule(1))  # [0, WHITE, BLACK]
    assert n.assign(10) == (0, 0)
    assert n.assign(12) == (0, BLACK)
    assert n.assign(13) == (1, 0)
    assert n.assign(17) == (2, WHITE)


def _oak_profile():
    p = load_profile("sim-dlp")
    return apply_update(p, {"camera": {"width": W, "height": H}, "code": {"name": "gray-3"}, "projector": {"width": 8}})


def test_oak_sensor_constructs_without_device():
    s = OakSensor(_oak_profile())
    assert s.info.name == "oak" and s.info.frames_per_stack == 5


def test_oak_sensor_host_pipeline_end_to_end():
    profile = _oak_profile()
    seqs = list(range(100, 110)) + list(range(111, 116))  # stack 2 loses one frame (seq 110)
    FakeMono.sequences = seqs
    pipeline = dai.Pipeline(createImplicitDevice=False)
    emitter = RecordingEmitter()
    sensor = OakSensor(profile, pipeline=pipeline, output_factory=lambda p: p.create(FakeMono).out,
                       emitter=emitter, max_frames=len(seqs))
    sensor.start()
    frames = []
    try:
        t0 = time.time()
        while len(frames) < len(seqs) and time.time() - t0 < 10:
            f = sensor.read(0.5)
            if f is not None:
                frames.append(f)
    finally:
        sensor.stop()
    assert [f.sequence for f in frames] == seqs
    f0 = frames[0]
    assert f0.image.dtype == np.uint8 and f0.image.shape == (H, W)
    assert np.array_equal(f0.image, _img(100))
    assert frames[3].timestamp_ns - f0.timestamp_ns == 3_000_000
    assert [parse_projector_frame(f.projector_frame).base for f in frames[:5]] == [0, 1, 2, WHITE, BLACK]
    assert [f.stack for f in frames] == [0] * 5 + [1] * 5 + [2] * 4 + [3]
    asm = StackAssembler(sensor.info.schedule)
    stacks = [s for f in frames if (s := asm.push(f))]
    asm.flush()
    assert [s.stack for s in stacks] == [0, 1]
    assert asm.counters.stacks_incomplete == 2 and asm.counters.sequence_gaps == 1
    # one dot + one flood command at start and after every frame; BLACK frames switch the dots off
    dots = [v for k, v in emitter.commands if k == "dot"]
    assert len(dots) == 1 + len(seqs) + 1 and dots[-1] == 0.0
    assert 0.0 in dots and 0.8 in dots


def test_frame_from_imgframe_uint16():
    f = dai.ImgFrame()
    img = (np.arange(H * W, dtype=np.uint16).reshape(H, W) * 50)
    f.setType(dai.ImgFrame.Type.RAW16)
    f.setWidth(W)
    f.setHeight(H)
    f.setData(img.view(np.uint8).reshape(-1))
    f.setSequenceNum(5)
    f.setTimestamp(datetime.timedelta(seconds=2, microseconds=3))
    out = frame_from_imgframe(f, projector_frame=WHITE, stack=1, clock_offset_ns=10)
    assert out.image.dtype == np.uint16 and np.array_equal(out.image, img)
    assert out.timestamp_ns == 2_000_003_000 + 10 and out.sequence == 5
    assert timedelta_ns(datetime.timedelta(microseconds=5)) == 5000
