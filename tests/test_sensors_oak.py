"""OAK backend without a device: host-side depthai pipeline through the real conversion path."""

from __future__ import annotations

import datetime
import time

import numpy as np
import pytest

import depthai as dai  # a hard dependency: a broken install must fail, not skip

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


def read_frames(sensor, count: int, timeout_s: float = 10.0) -> list:
    """Up to ``count`` frames read from a started sensor within ``timeout_s`` seconds."""
    frames: list = []
    t0 = time.time()
    while len(frames) < count and time.time() - t0 < timeout_s:
        f = sensor.read(0.5)
        if f is not None:
            frames.append(f)
    return frames


def _oak_profile():
    p = load_profile("sim-dlp")
    return apply_update(p, {"camera": {"width": W, "height": H}, "code": {"name": "gray-3"}, "projector": {"width": 8},
                            "decoder": {"min_disparity": -4, "max_disparity": 0}})  # a band that meets 8 columns


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
    try:
        frames = read_frames(sensor, len(seqs))
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
    # one dot + one flood command at start (position 0), after every frame for the frame lead_frames
    # ahead of it (position seq - first seq + lead), and at stop (off); BLACK (position 4 of 5)
    # switches the dots off, and the flood LED stays off (flood_intensity 0)
    lead = sensor.emitters.lead_frames
    assert lead == 2
    want = [0.8] + [0.0 if (s - seqs[0] + lead) % 5 == 4 else 0.8 for s in seqs] + [0.0]
    assert [k for k, _ in emitter.commands] == ["dot", "flood"] * len(want)
    assert [v for k, v in emitter.commands if k == "dot"] == want
    assert all(v == 0.0 for k, v in emitter.commands if k == "flood")


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


# -- stereo (CAM_B | CAM_C side by side) ---------------------------------------------------------

from edge.sensors.oak import (StereoPairer, geometry_from_calibration, geometry_mismatch,  # noqa: E402
                              stereo_frame_from_imgframes)


def _img_right(seq: int) -> np.ndarray:
    return ((np.arange(H * W).reshape(H, W) * 3 + 11 * seq) % 253).astype(np.uint8)


def _imgframe(image: np.ndarray, seq: int, ts_us: int, exposure_us: int = 4000) -> "dai.ImgFrame":
    f = dai.ImgFrame()
    f.setType(dai.ImgFrame.Type.GRAY8)
    f.setWidth(image.shape[1])
    f.setHeight(image.shape[0])
    f.setData(image.reshape(-1))
    f.setSequenceNum(seq)
    f.setTimestamp(datetime.timedelta(microseconds=ts_us))
    f.setTimestampDevice(datetime.timedelta(microseconds=ts_us))
    cam = f.cam
    cam.exposureTimeUs = exposure_us
    f.cam = cam
    return f


def _left(seq, ts_us=None):
    return _imgframe(_img(seq), seq, 1000 * seq if ts_us is None else ts_us)


def _right(seq, ts_us=None):
    return _imgframe(_img_right(seq), seq, 1000 * seq if ts_us is None else ts_us)


def test_stereo_pairer_rules():
    p = StereoPairer(window=2, max_skew_ns=500_000)
    p.push("left", _left(0))
    p.push("right", _right(0))
    assert [m.getSequenceNum() for m, _ in p.pop_ready()] == [0]
    p.push("left", _left(1))              # right 1 is lost
    p.push("right", _right(2))
    p.push("left", _left(2))
    assert p.pop_ready() == []            # 2 waits behind 1 while 1's partner may still come
    p.push("left", _left(3))
    p.push("right", _right(3))            # newest 3 >= 1 + window: left 1 is dropped
    pairs = p.pop_ready()
    assert [(lm.getSequenceNum(), rm.getSequenceNum()) for lm, rm in pairs] == [(2, 2), (3, 3)]
    p.push("right", _right(1))            # arrives after its slot closed
    p.push("right", _right(5))            # out of order: 5 before 4
    p.push("right", _right(4))
    p.push("right", _right(4))            # duplicate
    p.push("left", _left(4))
    p.push("left", _left(5, ts_us=5000 + 900))  # 0.9 ms skew > 0.5 ms: counters drifted apart
    assert [lm.getSequenceNum() for lm, _ in p.pop_ready()] == [4]
    p.push("left", _left(6))
    p.discard()
    assert p.counters.as_dict() == {"pairs": 4, "unpaired_left": 2, "unpaired_right": 0, "late": 1,
                                    "duplicates": 1, "desynced": 1}
    with pytest.raises(ValueError, match="side"):
        p.push("middle", _left(7))
    with pytest.raises(ValueError, match="window"):
        StereoPairer(window=0)


def test_stereo_frame_conversion():
    f = stereo_frame_from_imgframes(_left(7), _right(7), projector_frame=3, stack=2, clock_offset_ns=5)
    assert f.image.dtype == np.uint8 and f.image.shape == (H, 2 * W)
    assert np.array_equal(f.image[:, :W], _img(7)) and np.array_equal(f.image[:, W:], _img_right(7))
    assert (f.sequence, f.timestamp_ns, f.exposure_us, f.projector_frame, f.stack) == (7, 7_000_005, 4000.0, 3, 2)
    with pytest.raises(ValueError, match="sequence"):
        stereo_frame_from_imgframes(_left(7), _right(8), projector_frame=0, stack=0)
    small = _imgframe(np.zeros((H, W - 2), np.uint8), 7, 0)
    with pytest.raises(ValueError, match="same shape"):
        stereo_frame_from_imgframes(_left(7), small, projector_frame=0, stack=0)


SW, SH, SHIFT = 48, 24, 3  # stereo test frames; the left image sees the right one shifted by SHIFT px
_DOTS = np.random.default_rng(5).random((SH, SW)) < 0.15


def _stereo_img(seq: int, side: str) -> np.ndarray:
    """Slot ``seq % 4`` of code 1101: ambient 40 plus 150 on the dots when the chip is 1."""
    dots = np.roll(_DOTS, SHIFT, axis=1) if side == "left" else _DOTS
    chip = "1101"[seq % 4] == "1"
    return (40 + 150 * chip * dots + (side == "right")).astype(np.uint8)


class _Side(dai.node.ThreadedHostNode):
    """Sends one camera's GRAY8 ImgFrames in lock step with the other side (a shared barrier):
    ``steps`` holds a sequence number or None (frame lost) per step."""

    side = "left"
    steps: list = []
    barrier = None
    skew_us: dict = {}

    def __init__(self):
        super().__init__()
        self.out = self.createOutput()

    def run(self):
        for seq in self.steps:
            self.barrier.wait(timeout=10)
            if seq is not None:
                ts = 1000 * seq + self.skew_us.get(seq, 0)
                self.out.send(_imgframe(_stereo_img(seq, self.side), seq, ts))
            time.sleep(0.001)


class _LeftSide(_Side):
    side = "left"


class _RightSide(_Side):
    side = "right"


def _oak_dots_profile():
    p = load_profile("oak-d-pro")
    return apply_update(p, {"camera": {"width": SW, "height": SH}, "projector": {"width": SW, "height": SH},
                            "decoder": {"min_disparity": 1, "max_disparity": 8}})


def test_oak_sensor_stereo_constructs_without_device():
    s = OakSensor(_oak_dots_profile())
    assert s.stereo and s.info.layout == "slots" and s.info.frames_per_stack == 4
    assert s.info.metadata["camera"] == "CAM_B|CAM_C" and s.pairer.max_skew_ns == int(0.5e9 / 60)
    assert not OakSensor(_oak_profile()).stereo


def test_oak_sensor_stereo_host_pipeline_end_to_end():
    import threading

    from edge.runtime.dots import DotsPipeline

    profile = _oak_dots_profile()
    n = 20
    left = [s for s in range(n) if s != 9]       # left loses 9
    left[5], left[6] = left[6], left[5]           # and sends 6 before 5
    left.insert(9, None)
    right = [s if s != 13 else None for s in range(n)]  # right loses 13
    assert len(left) == len(right) == n
    _LeftSide.steps, _RightSide.steps = left, right
    _Side.barrier = threading.Barrier(2)
    _RightSide.skew_us = {2: 3000}               # pair 2: timestamps 3 ms apart
    pipeline = dai.Pipeline(createImplicitDevice=False)
    emitter = RecordingEmitter()
    sensor = OakSensor(profile, pipeline=pipeline, emitter=emitter, max_skew_ns=1_000_000,
                       output_factory=lambda p: (p.create(_LeftSide).out, p.create(_RightSide).out))
    expected = [s for s in range(n) if s not in (2, 9, 13)]
    sensor.start()
    frames = []
    try:
        t0 = time.time()
        while len(frames) < len(expected) and time.time() - t0 < 15:
            f = sensor.read(0.5)
            if f is not None:
                frames.append(f)
    finally:
        sensor.stop()
    assert [f.sequence for f in frames] == expected
    for f in frames:
        assert f.image.dtype == np.uint8 and f.image.shape == (SH, 2 * SW)
        assert np.array_equal(f.image[:, :SW], _stereo_img(f.sequence, "left"))
        assert np.array_equal(f.image[:, SW:], _stereo_img(f.sequence, "right"))
        assert f.timestamp_ns - frames[0].timestamp_ns == 1_000_000 * f.sequence
        assert f.exposure_us == 4000.0
        assert f.stack == f.sequence // 4 and parse_projector_frame(f.projector_frame).slot == f.sequence % 4
    assert sensor.stats() == {"frames": len(expected), "pairs": len(expected), "unpaired_left": 1,
                              "unpaired_right": 1, "late": 0, "duplicates": 0, "desynced": 1}
    asm = StackAssembler(sensor.info.schedule)
    stacks = [s for f in frames if (s := asm.push(f))]
    asm.flush()
    assert [s.stack for s in stacks] == [1, 4] and asm.counters.stacks_incomplete == 3
    # the dots pipeline block-matches left against right: disparity SHIFT, depth f * B / SHIFT (doffs 0)
    result = DotsPipeline(profile).process(stacks[0])
    g = profile.geometry
    depth = result.depth_mm[:, 12:-12]
    valid = depth[depth > 0]
    assert valid.size > 0.5 * depth.size
    assert np.median(valid) == round(1000 * g.focal_px * g.baseline_m / SHIFT)
    # emitters: 1101 -> dots on, on, off, on; set on start, ahead of each newest frame, off on stop
    dots = [v for k, v in emitter.commands if k == "dot"]
    assert dots[0] == 0.8 and dots[-1] == 0.0 and set(dots) == {0.0, 0.8} and 3 <= len(dots) <= n + 2


def test_geometry_from_calibration():
    S = dai.CameraBoardSocket
    calib = dai.CalibrationHandler()
    eye = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
    calib.setCameraIntrinsics(S.CAM_B, [[800.0, 0, 640], [0, 800.0, 400], [0, 0, 1]], 1280, 800)
    calib.setCameraIntrinsics(S.CAM_C, [[790.0, 0, 630], [0, 790.0, 405], [0, 0, 1]], 1280, 800)
    calib.setCameraExtrinsics(S.CAM_B, S.CAM_C, eye, [-7.5, 0.0, 0.0], [-7.5, 0.0, 0.0])  # cm
    g = geometry_from_calibration(calib, 640, 400)
    assert g["baseline_m"] == pytest.approx(0.075, rel=1e-6)
    assert (g["focal_px"], g["cx_camera"], g["cx_projector"], g["cy"]) == (395.0, 315.0, 315.0, 202.5)
    profile = load_profile("oak-d-pro")  # nominal: 75 mm, f 381, cx 320, cy 200
    bad = geometry_mismatch(profile.geometry, g)
    assert [b.split(":")[0] for b in bad] == ["focal_px"]
    updated = apply_update(profile, {"geometry": g})
    assert geometry_mismatch(updated.geometry, g) == []
    assert updated.geometry.cx_projector - updated.geometry.cx_camera == 0  # doffs = 0
