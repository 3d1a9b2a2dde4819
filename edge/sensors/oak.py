"""Luxonis OAK-D Pro through depthai v3: mono or stereo frames, IR emitters on the source-code schedule.

Two modes (``OakSensor(stereo=...)``; default: stereo for dot profiles, mono otherwise):

* **mono** (coded column patterns from an external projector): the left mono camera (CAM_B) only,
  frames ``(H, W)``.
* **stereo** (dot profiles such as ``oak-d-pro``): both mono cameras, CAM_B (left) and CAM_C (right),
  rectified on the device, paired on the host and emitted as one side-by-side ``(H, 2W)`` frame,
  left | right, which `edge.runtime.dots.DotsPipeline` de-spreads and block-matches (left against
  the right image; the profile's "projector" is the right camera, ``doffs = 0``).

Pipeline (depthai 3.x API, checked by introspection of depthai 3.12)::

    pipeline = dai.Pipeline()                                   # implicit device
    left = pipeline.create(dai.node.Camera).build(dai.CameraBoardSocket.CAM_B)
    right = pipeline.create(dai.node.Camera).build(dai.CameraBoardSocket.CAM_C)
    lo = left.requestOutput((W, H), dai.ImgFrame.Type.GRAY8, fps=rate)      # same for right
    stereo = pipeline.create(dai.node.StereoDepth).build(lo, ro)            # rectification
    ql = stereo.rectifiedLeft.createOutputQueue(maxSize=64, blocking=False)  # same for right
    pipeline.start()
    device = pipeline.getDefaultDevice()
    device.setIrLaserDotProjectorIntensity(x) / device.setIrFloodLightIntensity(x)   # 0..1

Rectification: the raw mono images are not row-aligned, and block matching searches along rows,
so the default stereo outputs are StereoDepth's ``rectifiedLeft`` / ``rectifiedRight`` (StereoDepth
runs on RVC2 devices such as the OAK-D Pro; the newer ``node.Rectification`` may not).  Its depth
output is not used.  ``rectify=False`` streams the raw camera outputs instead.

Pairing (`StereoPairer`): by **sequence number**.  On the OAK-D Pro both OV9282 monos are
hardware frame-synchronised and report the same sequence number for the same exposure, so the
sequence number is an exact key, whereas device timestamps of the two sides differ by readout
jitter and a timestamp tolerance can pair the wrong exposures when frames are lost at high rates.
The device timestamps serve as a cross-check: a pair whose timestamps differ by more than
``max_skew_ns`` (default half a frame period) is dropped and counted as ``desynced`` (it would mean
the two sequence counters drifted apart).  A frame whose partner has not arrived once a frame
``window`` sequence numbers newer was seen is dropped and counted (``unpaired_left`` /
``unpaired_right``); a frame arriving after its slot was closed is dropped as ``late``.  Pairs
leave in increasing sequence order, so an out-of-order frame within the window is still paired.
(`dai.node.Sync` was not used: it pairs by timestamp threshold and drops without counting.)

Each pair (or mono `dai.ImgFrame`) becomes a `Frame` (`frame_from_imgframe`,
`stereo_frame_from_imgframes`): ``getFrame()`` (copied; stereo: ``np.hstack``), ``getSequenceNum()``,
``getTimestamp()`` (the device capture time converted by depthai to the host steady clock, mapped to
wall-clock ns; the left one for a pair), ``getExposureTime()`` (microseconds, left camera).  The
projector frame of a camera frame follows from its sequence number: position
``(seq - seq0) % frames_per_stack`` of the stack schedule, stack id ``(seq - seq0) // frames_per_stack``;
so a lost frame or pair leaves a hole that the assembler drops.

Emitters: depthai has no per-frame emitter API.  With a device and ``[oak] emitter_control =
"script"`` (default) the switching runs ON THE DEVICE, as depthai's documented dot/flood
alternation example does: a `dai.node.Script` on LEON_CSS (`emitter_script`) is woken by every
left frame (its ``frame`` input, linked to the left output, non-blocking, queue 1), and for the
frame with sequence number ``s`` sets ``Device.setIrLaserDotProjectorIntensity`` /
``Device.setIrFloodLightIntensity`` for frame ``s + lead_frames`` from a per-position table of the
schedule (`EmitterSchedule.table`); stack numbering is then absolute (``seq0 = 0``) so host and
device agree on the schedule position ``seq % frames_per_stack`` without talking.  A new table
(`OakSensor.apply_settings`, e.g. a live ``oak`` config update) goes to the script's ``config``
input from a host input queue.  ``emitter_control = "host"``, an explicit ``emitter`` object or a
host-only pipeline use host calls instead: when a frame with a new highest sequence number ``s``
arrives, the host sets the emitters for frame ``s + lead_frames``.  Intensities and lead frames
come from the profile's ``[oak]`` table.  The emitter pulses follow the left camera strobe (CAM_B).

Device status (`OakSensor.device_status`, in the service status as ``sensor_device``): device id
(serial), product name, depthai / bootloader version, USB speed (``getUsbSpeed``), chip
temperature (``getChipTemperature().average``, degC), LEON CSS / MSS CPU load
(``getLeonCssCpuUsage`` / ``getLeonMssCpuUsage``, percent), the emitter settings, and the last
frame's exposure and sensitivity (ISO, the sensor's gain).

Geometry: with a device, `start` reads the calibration (``device.readCalibration()``) and
`geometry_from_calibration` gives the rectified geometry (focal length and principal point of the
right camera at the output size, baseline CAM_C-CAM_B from cm to m, ``cx_projector = cx_camera``)
in ``OakSensor.device_geometry`` and the sensor metadata (which notes a mismatch over 2 % with the
profile); `edge.runtime.service.Service` applies ``device_geometry`` to its profile right after
``start``, so depth, camera info and point clouds use the device's calibration.

NOT verified on hardware here (no device on the build machine): opening a device, the emitter
command latency (``lead_frames``), the exact pulse/exposure alignment, frame rates above 60 fps,
that both monos report equal sequence numbers and timestamps within ``max_skew_ns`` for a pair
(documented behaviour of the synced OV9282 pair), that StereoDepth's rectified outputs keep the
cameras' sequence numbers and use the right camera's intrinsics (the basis of
`geometry_from_calibration`), and real dot depth.  Verified without a device: construction, the
ImgFrame -> Frame conversion (mono and side by side), pairing with lost, out-of-order, late and
desynced frames, stack numbering, the emitter schedule, and geometry from an in-memory
``dai.CalibrationHandler``, through host-side pipelines (``dai.Pipeline(createImplicitDevice=False)``
with ``dai.node.ThreadedHostNode`` subclasses sending ``dai.ImgFrame`` objects) that use the same
queue, pairing and conversion code as a device - see tests/test_sensors_oak.py.
"""

from __future__ import annotations

import datetime
import threading
import time
from collections import deque
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from .base import EndOfStream, Frame, SensorInfo, parse_projector_frame

_US = datetime.timedelta(microseconds=1)
#: relative difference between the profile's and the device's geometry that the metadata flags
GEOMETRY_TOLERANCE = 0.02


def timedelta_ns(td: datetime.timedelta) -> int:
    """A depthai timestamp (datetime.timedelta, microsecond resolution) in integer ns."""
    return (td // _US) * 1000


def imgframe_image(msg: Any) -> np.ndarray:
    """(H, W) uint8 / uint16 copy of a `dai.ImgFrame`'s pixels (GRAY8/RAW8 -> uint8, RAW16 -> uint16)."""
    image = np.array(msg.getFrame(), copy=True)
    if image.ndim == 3 and image.shape[2] == 1:
        image = image[:, :, 0]
    if image.ndim != 2:
        raise ValueError(f"OAK frames must be single-channel mono images, got shape {image.shape}")
    if image.dtype not in (np.uint8, np.uint16):
        raise ValueError(f"OAK frames must be uint8 or uint16, got {image.dtype}")
    return image


def frame_from_imgframe(msg: Any, *, projector_frame: int, stack: int, clock_offset_ns: int = 0) -> Frame:
    """Convert one `dai.ImgFrame` (GRAY8/RAW8 -> uint8, RAW16/RAW10.. unpacked -> uint16) to a `Frame`.

    clock_offset_ns: added to the frame's steady-clock timestamp to put it on the host wall clock.
    """
    return Frame(
        image=imgframe_image(msg),
        sequence=int(msg.getSequenceNum()),
        timestamp_ns=timedelta_ns(msg.getTimestamp()) + int(clock_offset_ns),
        exposure_us=msg.getExposureTime() / _US,
        projector_frame=int(projector_frame),
        stack=int(stack),
    )


def stereo_frame_from_imgframes(left: Any, right: Any, *, projector_frame: int, stack: int,
                                clock_offset_ns: int = 0) -> Frame:
    """One side-by-side `Frame` from a left (CAM_B) and right (CAM_C) `dai.ImgFrame` of one exposure.

    image: (H, 2W) ``left | right``, dtype of the inputs (both must match in shape and dtype).
    sequence, timestamp_ns (host wall clock, see `frame_from_imgframe`), exposure_us: the left frame's.
    """
    if left.getSequenceNum() != right.getSequenceNum():
        raise ValueError(f"a stereo pair needs equal sequence numbers, got left {left.getSequenceNum()} "
                         f"and right {right.getSequenceNum()}")
    li, ri = imgframe_image(left), imgframe_image(right)
    if li.shape != ri.shape or li.dtype != ri.dtype:
        raise ValueError(f"left and right frames must have the same shape and dtype, got {li.shape} {li.dtype} "
                         f"and {ri.shape} {ri.dtype}")
    return Frame(
        image=np.hstack([li, ri]),
        sequence=int(left.getSequenceNum()),
        timestamp_ns=timedelta_ns(left.getTimestamp()) + int(clock_offset_ns),
        exposure_us=left.getExposureTime() / _US,
        projector_frame=int(projector_frame),
        stack=int(stack),
    )


@dataclass
class PairCounters:
    """Counters of `StereoPairer` (monotonically increasing), in frames.

    pairs: pairs delivered; unpaired_left / unpaired_right: left / right frames dropped because
    their partner never came within the window; late: frames that arrived after their sequence
    number was closed (paired, dropped or passed); duplicates: a second frame with a pending
    sequence number on the same side; desynced: pairs dropped for a device-timestamp skew over
    ``max_skew_ns``.
    """

    pairs: int = 0
    unpaired_left: int = 0
    unpaired_right: int = 0
    late: int = 0
    duplicates: int = 0
    desynced: int = 0

    def as_dict(self) -> dict[str, int]:
        return dict(self.__dict__)


class StereoPairer:
    """Pairs left and right `dai.ImgFrame`s by sequence number (see module docstring).

    window: frames a partner may lag behind the newest sequence number seen (either side) before
        the waiting frame is dropped; also the extra delay of the pairs behind a lost frame.
    max_skew_ns: largest |left - right| device timestamp (``getTimestampDevice``) of a pair, ns;
        None = no check.
    ``push(side, msg)`` with side ``"left"`` / ``"right"``; ``pop_ready()`` -> list of (left, right)
    in increasing sequence order; ``discard()`` drops (and counts) whatever still waits.
    Not thread-safe: one reader thread.
    """

    SIDES = ("left", "right")

    def __init__(self, *, window: int = 4, max_skew_ns: int | None = None) -> None:
        if window < 1:
            raise ValueError(f"pairing window must be >= 1 frame, got {window}")
        if max_skew_ns is not None and max_skew_ns < 0:
            raise ValueError(f"max_skew_ns must be >= 0 or None, got {max_skew_ns}")
        self.window = int(window)
        self.max_skew_ns = None if max_skew_ns is None else int(max_skew_ns)
        self.counters = PairCounters()
        self.newest: int | None = None
        self.closed_through: int | None = None  # every sequence <= this is emitted or dropped
        self._pending: dict[str, dict[int, Any]] = {"left": {}, "right": {}}

    def push(self, side: str, msg: Any) -> None:
        if side not in self._pending:
            raise ValueError(f"stereo side must be 'left' or 'right', got {side!r}")
        seq = int(msg.getSequenceNum())
        if self.closed_through is not None and seq <= self.closed_through:
            self.counters.late += 1
            return
        pending = self._pending[side]
        if seq in pending:
            self.counters.duplicates += 1
            return
        pending[seq] = msg
        self.newest = seq if self.newest is None else max(self.newest, seq)

    def _close(self, seq: int) -> None:
        self.closed_through = seq if self.closed_through is None else max(self.closed_through, seq)

    def _drop_one_sided(self, seq: int) -> None:
        for side in self.SIDES:
            if self._pending[side].pop(seq, None) is not None:
                setattr(self.counters, f"unpaired_{side}", getattr(self.counters, f"unpaired_{side}") + 1)

    def pop_ready(self) -> list[tuple[Any, Any]]:
        """Complete pairs that may leave now (increasing sequence order); drops stale one-sided frames."""
        out: list[tuple[Any, Any]] = []
        left, right = self._pending["left"], self._pending["right"]
        for seq in sorted(left.keys() | right.keys()):
            if seq in left and seq in right:
                lmsg, rmsg = left.pop(seq), right.pop(seq)
                self._close(seq)
                skew = abs(timedelta_ns(lmsg.getTimestampDevice()) - timedelta_ns(rmsg.getTimestampDevice()))
                if self.max_skew_ns is not None and skew > self.max_skew_ns:
                    self.counters.desynced += 1
                    continue
                self.counters.pairs += 1
                out.append((lmsg, rmsg))
            elif seq <= self.newest - self.window:
                self._drop_one_sided(seq)
                self._close(seq)
            else:
                break  # the partner may still come; later pairs wait to keep the order
        return out

    def discard(self) -> None:
        """Drop and count every waiting frame (end of stream)."""
        for seq in sorted(self._pending["left"].keys() | self._pending["right"].keys()):
            self._drop_one_sided(seq)
            self._close(seq)


@dataclass
class StackNumbering:
    """Sequence number -> (stack id, projector frame id) for a fixed, repeating schedule.

    The first frame seen starts stack 0 at schedule position 0 (``seq0``).
    """

    schedule: np.ndarray
    seq0: int | None = None

    def assign(self, sequence: int) -> tuple[int, int]:
        if self.seq0 is None:
            self.seq0 = int(sequence)
        k = int(sequence) - self.seq0
        stack, pos = divmod(k, len(self.schedule))
        return stack, int(self.schedule[pos])


@dataclass
class EmitterSchedule:
    """Emitter intensities for every schedule position (dot projector, flood light), 0..1.

    A slot whose source-code chip is 1 and whose projector frame is not BLACK turns the dot
    projector on at ``dot_intensity``; everything else turns it off.  ``flood_intensity`` lights the
    flood LED on the WHITE calibration frames (0 = never).
    """

    schedule: np.ndarray
    source_code: str = "1"
    dot_intensity: float = 0.8
    flood_intensity: float = 0.0
    lead_frames: int = 2

    def __post_init__(self) -> None:
        if not self.source_code or set(self.source_code) - {"0", "1"}:
            raise ValueError(f"source code must be a non-empty bit string, got {self.source_code!r}")
        for name in ("dot_intensity", "flood_intensity"):
            v = getattr(self, name)
            if not 0.0 <= v <= 1.0:
                raise ValueError(f"{name} must be in 0..1, got {v}")
        if self.lead_frames < 0:
            raise ValueError(f"lead_frames must be >= 0, got {self.lead_frames}")

    def table(self) -> tuple[list[float], list[float]]:
        """(dot, flood) intensity lists, one entry per schedule position (the Script node's table)."""
        pairs = [self.intensities(i) for i in range(len(self.schedule))]
        return [d for d, _ in pairs], [f for _, f in pairs]

    def intensities(self, position: int) -> tuple[float, float]:
        """(dot, flood) for schedule position ``position`` (wraps around)."""
        pf = parse_projector_frame(int(self.schedule[position % len(self.schedule)]))
        chip = self.source_code[pf.slot % len(self.source_code)] == "1"
        dot = self.dot_intensity if chip and not pf.is_black else 0.0
        flood = self.flood_intensity if chip and pf.is_white else 0.0
        return dot, flood


@dataclass
class RecordingEmitter:
    """Emitter control without a device: remembers the commands (tests, dry runs)."""

    commands: list[tuple[str, float]] = field(default_factory=list)

    def setIrLaserDotProjectorIntensity(self, intensity: float, mask: int = -1) -> bool:  # noqa: N802 (depthai name)
        self.commands.append(("dot", float(intensity)))
        return True

    def setIrFloodLightIntensity(self, intensity: float, mask: int = -1) -> bool:  # noqa: N802
        self.commands.append(("flood", float(intensity)))
        return True


def _config_text(emitters: EmitterSchedule) -> str:
    dot, flood = emitters.table()
    return f"{','.join(f'{v:.6g}' for v in dot)};{','.join(f'{v:.6g}' for v in flood)};{int(emitters.lead_frames)}"


def emitter_script(emitters: EmitterSchedule) -> str:
    """The device-side Python of the emitter Script node (runs on LEON_CSS; see module docstring).

    Globals provided by depthai on the device: ``node`` (inputs ``frame`` and ``config``) and
    ``Device``.  The table is ``"<dot,...>;<flood,...>;<lead>"`` text, also the format of the
    messages on ``config``; intensities are only sent when they change.
    """
    return f"""
def parse(text):
    parts = text.split(';')
    return [float(v) for v in parts[0].split(',')], [float(v) for v in parts[1].split(',')], int(parts[2])

dot, flood, lead = parse({_config_text(emitters)!r})
last = None
while True:
    cfg = node.io['config'].tryGet()
    if cfg is not None:
        dot, flood, lead = parse(bytes(cfg.getData()).decode())
    frame = node.io['frame'].get()
    pos = (frame.getSequenceNum() + lead) % len(dot)
    want = (dot[pos], flood[pos])
    if want != last:
        Device.setIrLaserDotProjectorIntensity(want[0])
        Device.setIrFloodLightIntensity(want[1])
        last = want
"""


def emitter_script_node(pipeline: Any, tick: Any, emitters: EmitterSchedule) -> tuple[Any, Any]:
    """Create the emitter Script node on the device, link ``tick`` (the left camera output) to its
    ``frame`` input; returns (script node, host input queue of its ``config`` input)."""
    import depthai as dai

    script = pipeline.create(dai.node.Script)
    script.setProcessor(dai.ProcessorType.LEON_CSS)
    script.setScript(emitter_script(emitters), "edge-emitters")
    frame_in = script.inputs["frame"]
    frame_in.setBlocking(False)
    frame_in.setMaxSize(1)
    tick.link(frame_in)
    config_queue = script.inputs["config"].createInputQueue(maxSize=4, blocking=False)
    return script, config_queue


def config_buffer(emitters: EmitterSchedule) -> Any:
    """A `dai.Buffer` holding a new emitter table for the Script node's ``config`` input."""
    import depthai as dai

    buf = dai.Buffer()
    buf.setData(list(_config_text(emitters).encode()))
    return buf


def camera_output(pipeline: Any, width: int, height: int, fps: float) -> Any:
    """The real camera: CAM_B (left mono) node's GRAY8 output of ``width`` x ``height`` at ``fps``."""
    import depthai as dai

    cam = pipeline.create(dai.node.Camera).build(dai.CameraBoardSocket.CAM_B)
    return cam.requestOutput((int(width), int(height)), dai.ImgFrame.Type.GRAY8, fps=float(fps))


def stereo_outputs(pipeline: Any, width: int, height: int, fps: float, *, rectify: bool = True) -> tuple[Any, Any]:
    """The real stereo pair: (left, right) outputs of CAM_B and CAM_C, GRAY8 ``width`` x ``height`` at ``fps``.

    rectify: route both through a StereoDepth node and return its ``rectifiedLeft`` /
    ``rectifiedRight`` (rows aligned; borders filled black); False: the raw camera outputs.
    """
    import depthai as dai

    outs = []
    for socket in (dai.CameraBoardSocket.CAM_B, dai.CameraBoardSocket.CAM_C):
        cam = pipeline.create(dai.node.Camera).build(socket)
        outs.append(cam.requestOutput((int(width), int(height)), dai.ImgFrame.Type.GRAY8, fps=float(fps)))
    if not rectify:
        return outs[0], outs[1]
    stereo = pipeline.create(dai.node.StereoDepth).build(outs[0], outs[1])
    stereo.setRectification(True)
    stereo.setRectifyEdgeFillColor(0)
    return stereo.rectifiedLeft, stereo.rectifiedRight


def geometry_from_calibration(calibration: Any, width: int, height: int) -> dict[str, float]:
    """Rectified stereo geometry of an OAK from its `dai.CalibrationHandler`, for ``width`` x ``height`` frames.

    Returns the profile ``[geometry]`` keys: ``focal_px`` (fx), ``cx_camera`` = ``cx_projector`` and
    ``cy`` of the right camera (CAM_C) intrinsics scaled to the frame size (the rectified pair shares
    them, so ``doffs = 0``), and ``baseline_m``: the CAM_C - CAM_B distance from the calibrated
    extrinsics, which depthai gives in centimetres, divided by 100.
    """
    import depthai as dai

    k = np.asarray(calibration.getCameraIntrinsics(dai.CameraBoardSocket.CAM_C, int(width), int(height)), float)
    if k.shape != (3, 3) or not np.all(np.isfinite(k)) or k[0, 0] <= 0:
        raise ValueError(f"OAK calibration: expected a 3x3 intrinsics matrix with fx > 0 for CAM_C, got {k.tolist()}")
    baseline_cm = float(calibration.getBaselineDistance(dai.CameraBoardSocket.CAM_C, dai.CameraBoardSocket.CAM_B,
                                                        False))
    if not np.isfinite(baseline_cm) or abs(baseline_cm) <= 0:
        raise ValueError(f"OAK calibration: expected a non-zero CAM_C-CAM_B baseline, got {baseline_cm} cm")
    return {"baseline_m": abs(baseline_cm) / 100.0, "focal_px": float(k[0, 0]), "cx_camera": float(k[0, 2]),
            "cx_projector": float(k[0, 2]), "cy": float(k[1, 2])}


def geometry_mismatch(profile_geometry: Any, device: dict[str, float],
                      rel_tol: float = GEOMETRY_TOLERANCE) -> list[str]:
    """Keys where the profile's geometry differs from ``device`` by more than ``rel_tol`` (relative; pixels
    for cx/cy relative to the focal length)."""
    bad = []
    for key, value in device.items():
        ref = abs(value) if key in ("baseline_m", "focal_px") else max(1.0, device["focal_px"])
        if abs(float(getattr(profile_geometry, key)) - value) > rel_tol * ref:
            bad.append(f"{key}: profile {float(getattr(profile_geometry, key)):.4g}, device {value:.4g}")
    return bad


class OakSensor:
    """OAK-D Pro backend (see module docstring).  Constructing it touches no device.

    profile: an `edge.profiles.Profile` (camera size/rate, code, source code).
    stereo: pair CAM_B and CAM_C into ``(H, 2W)`` frames (default: for ``projector.kind = "dots"``).
    pipeline: a depthai pipeline to use (default: ``dai.Pipeline()`` with the implicit device,
        created in `start`); output_factory(pipeline) -> node output (mono, default `camera_output`)
        or (left, right) outputs (stereo, default `stereo_outputs`);
    emitter: object with the two depthai emitter setters (default: the pipeline's device; given, the
        host switches the emitters).  dot_intensity, flood_intensity, lead_frames,
        emitter_control ("script" | "host"): default from the profile's ``[oak]`` table.
    pair_window, max_skew_ns: `StereoPairer` settings (default skew: half a frame period).
    max_frames: end the stream (EndOfStream) after this many frames.
    """

    def __init__(self, profile, *, stereo: bool | None = None, pipeline: Any = None,
                 output_factory: Callable[[Any], Any] | None = None,
                 emitter: Any = None, dot_intensity: float | None = None, flood_intensity: float | None = None,
                 lead_frames: int | None = None, max_frames: int | None = None, rectify: bool = True,
                 pair_window: int = 4, max_skew_ns: int | None = None, emitter_control: str | None = None) -> None:
        from edge.device import DeviceModel

        model = DeviceModel.from_profile(profile)
        n, L = model.n_code_frames, model.source_length
        layout = model.layout  # dots profiles: one dot frame in the L source-code slots
        cam = profile.camera
        self.stereo = (profile.projector.kind == "dots") if stereo is None else bool(stereo)
        self.profile = profile
        meta = {"device": "OAK-D Pro", "camera": "CAM_B|CAM_C" if self.stereo else "CAM_B"}
        if self.stereo:
            meta.update(frame="left|right side by side (H, 2W)", pairing="sequence number",
                        rectified=str(bool(rectify)))
        self.info = SensorInfo(
            name="oak", width=cam.width, height=cam.height, bits=8, fps=cam.rate_hz,
            n_code_frames=n, source_length=L, metadata=meta, layout=layout)
        self._schedule = self.info.schedule
        self.numbering = StackNumbering(self._schedule)
        oak = profile.oak
        self.emitters = EmitterSchedule(
            self._schedule, profile.code.source or "1",
            oak.dot_intensity if dot_intensity is None else dot_intensity,
            oak.flood_intensity if flood_intensity is None else flood_intensity,
            oak.lead_frames if lead_frames is None else lead_frames)
        self.emitter_control = emitter_control or oak.emitter_control
        if self.emitter_control not in ("script", "host"):
            raise ValueError(f"emitter_control must be 'script' or 'host', got {self.emitter_control!r}")
        self.emitters_on_device = False  # True once the Script node switches them (start with a device)
        self._script_config = None
        self._device = None
        self._last_exposure_us: float | None = None
        self._last_iso: int | None = None
        if max_skew_ns is None and cam.rate_hz > 0:
            max_skew_ns = int(0.5e9 / cam.rate_hz)
        self.pairer = StereoPairer(window=pair_window, max_skew_ns=max_skew_ns)
        self.device_geometry: dict[str, float] | None = None
        self._pipeline = pipeline
        if output_factory is None:
            if self.stereo:
                def output_factory(p):
                    return stereo_outputs(p, cam.width, cam.height, cam.rate_hz, rectify=rectify)
            else:
                def output_factory(p):
                    return camera_output(p, cam.width, cam.height, cam.rate_hz)
        self._output_factory = output_factory
        self._emitter = emitter
        self._queues: dict[str, Any] = {}
        self._ready: deque[Frame] = deque()
        self._clock_offset_ns = 0
        self._max_frames = max_frames
        self._frames = 0
        self._commanded: int | None = None  # newest sequence number the emitters were set for
        self._lock = threading.Lock()

    # -- lifetime ---------------------------------------------------------------------------

    def start(self) -> None:
        import depthai as dai

        if self._pipeline is None:
            self._pipeline = dai.Pipeline()
        outputs = self._output_factory(self._pipeline)
        if self.stereo:
            if not (isinstance(outputs, tuple) and len(outputs) == 2):
                raise ValueError(f"a stereo OAK output factory must return (left, right) outputs, got {outputs!r}")
            named = dict(zip(StereoPairer.SIDES, outputs))
        else:
            named = {"mono": outputs}
        self._queues = {k: o.createOutputQueue(maxSize=64, blocking=False) for k, o in named.items()}
        device = self._pipeline.getDefaultDevice()
        self._device = device
        if device is not None:
            self._read_calibration(device)
            if self.emitter_control == "script" and self._emitter is None:
                tick = named["left"] if self.stereo else named["mono"]
                _, self._script_config = emitter_script_node(self._pipeline, tick, self.emitters)
                self.emitters_on_device = True
                self.numbering.seq0 = 0  # absolute positions: the device computes seq % frames_per_stack
                self.info.metadata["emitter_control"] = "device Script node"
        self._clock_offset_ns = time.time_ns() - time.monotonic_ns()
        self._pipeline.start()
        if self._emitter is None:
            self._emitter = device if device is not None else self._pipeline.getDefaultDevice()
        if not self.emitters_on_device:
            self._set_emitters(0)

    def _read_calibration(self, device: Any) -> None:
        """Device calibration -> `device_geometry` and metadata (stereo profiles)."""
        cam = self.profile.camera
        meta = self.info.metadata
        try:
            meta["device_id"] = str(device.getDeviceId())
        except Exception:  # older firmware: no id; not fatal
            pass
        if not self.stereo:
            return
        self.device_geometry = geometry_from_calibration(device.readCalibration(), cam.width, cam.height)
        meta.update({f"calibration_{k}": f"{v:.6g}" for k, v in self.device_geometry.items()})
        bad = geometry_mismatch(self.profile.geometry, self.device_geometry)
        if bad:
            meta["geometry_warning"] = "profile geometry differs from the device calibration: " + "; ".join(bad)

    def stop(self) -> None:
        with self._lock:
            if self._pipeline is not None and self._queues:
                try:
                    if self._emitter is not None:
                        self._emitter.setIrLaserDotProjectorIntensity(0.0)
                        self._emitter.setIrFloodLightIntensity(0.0)
                finally:
                    if self._pipeline.isRunning():
                        self._pipeline.stop()
                    self._pipeline.wait()
                    self._queues = {}
                    self.pairer.discard()

    # -- frames -----------------------------------------------------------------------------

    def _set_emitters(self, position: int) -> None:
        dot, flood = self.emitters.intensities(position)
        self._emitter.setIrLaserDotProjectorIntensity(dot)
        self._emitter.setIrFloodLightIntensity(flood)

    def _saw_sequence(self, sequence: int) -> None:
        """A frame with ``sequence`` arrived: set the emitters ``lead_frames`` ahead of the newest one
        (host control only; the Script node does it on the device)."""
        if self.emitters_on_device or (self._commanded is not None and sequence <= self._commanded):
            return
        self._commanded = sequence
        if self.numbering.seq0 is None:
            self.numbering.seq0 = int(sequence)
        self._set_emitters(sequence - self.numbering.seq0 + self.emitters.lead_frames)

    def _emit(self, frame: Frame) -> Frame:
        self._frames += 1
        return frame

    def read(self, timeout_s: float = 1.0) -> Frame | None:
        if not self._queues:
            raise ValueError("OakSensor.read called before start()")
        if self._max_frames is not None and self._frames >= self._max_frames:
            raise EndOfStream()
        return self._read_stereo(timeout_s) if self.stereo else self._read_mono(timeout_s)

    def _ended(self) -> bool:
        return not self._pipeline.isRunning() and not any(q.has() for q in self._queues.values())

    def _read_mono(self, timeout_s: float) -> Frame | None:
        queue = self._queues["mono"]
        msg = queue.get(datetime.timedelta(seconds=timeout_s)) if timeout_s > 0 else queue.tryGet()
        if msg is None:
            if self._ended():
                raise EndOfStream()
            return None
        self._saw_sequence(int(msg.getSequenceNum()))
        self._note_exposure(msg)
        stack, projector_frame = self.numbering.assign(msg.getSequenceNum())
        return self._emit(frame_from_imgframe(msg, projector_frame=projector_frame, stack=stack,
                                              clock_offset_ns=self._clock_offset_ns))

    def _poll(self, timeout_s: float) -> None:
        """Move every waiting left/right message into the pairer (block up to ``timeout_s`` for one)."""
        import depthai as dai

        got = (dai.MessageQueue.getAny(self._queues, datetime.timedelta(seconds=timeout_s)) if timeout_s > 0
               else {k: m for k, q in self._queues.items() if (m := q.tryGet()) is not None})
        msgs = [(side, m) for side, m in got.items() if m is not None]
        for side, q in self._queues.items():
            msgs.extend((side, m) for m in (q.tryGetAll() or []))
        if msgs and self.numbering.seq0 is None:  # stack 0 starts at the oldest frame of the first batch
            self.numbering.seq0 = min(int(m.getSequenceNum()) for _, m in msgs)
        for side, m in msgs:
            self.pairer.push(side, m)
        if self.pairer.newest is not None:
            self._saw_sequence(self.pairer.newest)

    def _convert_ready(self) -> None:
        for left, right in self.pairer.pop_ready():
            self._note_exposure(left)
            stack, projector_frame = self.numbering.assign(left.getSequenceNum())
            self._ready.append(stereo_frame_from_imgframes(left, right, projector_frame=projector_frame, stack=stack,
                                                           clock_offset_ns=self._clock_offset_ns))

    def _read_stereo(self, timeout_s: float) -> Frame | None:
        deadline = time.monotonic() + max(0.0, timeout_s)
        while not self._ready:
            remaining = deadline - time.monotonic()
            self._poll(max(0.0, remaining))
            self._convert_ready()
            if self._ready:
                break
            if self._ended():
                self.pairer.discard()
                raise EndOfStream()
            if remaining <= 0:
                return None
        return self._emit(self._ready.popleft())

    def _note_exposure(self, msg: Any) -> None:
        try:
            self._last_exposure_us = msg.getExposureTime() / _US
            self._last_iso = int(msg.getSensitivity())
        except Exception:  # host-made frames may lack them
            pass

    def apply_settings(self, oak: Any) -> None:
        """Use new ``[oak]`` settings (dot_intensity, flood_intensity, lead_frames) while running: a new
        `EmitterSchedule`; with the Script node, its table is sent to the device.  emitter_control
        cannot change while running (ValueError)."""
        if oak.emitter_control != self.emitter_control:
            raise ValueError(f"oak.emitter_control cannot change while running (is {self.emitter_control!r})")
        emitters = EmitterSchedule(self._schedule, self.profile.code.source or "1", oak.dot_intensity,
                                   oak.flood_intensity, oak.lead_frames)
        with self._lock:
            self.emitters = emitters
            if self._script_config is not None:
                self._script_config.send(config_buffer(emitters))

    def device_status(self) -> dict[str, Any]:
        """What users expect of a depth camera's status (see module docstring); keys whose device
        call failed or that need a device are None."""
        import depthai as dai

        e = self.emitters
        out: dict[str, Any] = {
            "serial": self.info.metadata.get("device_id"), "product": None, "depthai_version": dai.__version__,
            "bootloader_version": None, "usb_speed": None, "temperature_c": None,
            "cpu_css_percent": None, "cpu_mss_percent": None,
            "dot_intensity": e.dot_intensity, "flood_intensity": e.flood_intensity, "lead_frames": e.lead_frames,
            "emitter_control": "device script" if self.emitters_on_device else "host",
            "exposure_us": self._last_exposure_us, "iso": self._last_iso,
        }
        d = self._device
        if d is None:
            return out

        def ask(key: str, fn: Callable[[], Any]) -> None:
            try:
                out[key] = fn()
            except Exception:
                pass

        ask("product", lambda: str(d.getProductName()))
        ask("bootloader_version", lambda: str(d.getBootloaderVersion()))
        ask("usb_speed", lambda: str(d.getUsbSpeed()).split(".")[-1])
        ask("temperature_c", lambda: round(float(d.getChipTemperature().average), 2))
        ask("cpu_css_percent", lambda: round(100.0 * float(d.getLeonCssCpuUsage().average), 1))
        ask("cpu_mss_percent", lambda: round(100.0 * float(d.getLeonMssCpuUsage().average), 1))
        return out

    def stats(self) -> dict[str, int]:
        """Frames delivered and (stereo) the pairing counters (`PairCounters`)."""
        out = {"frames": self._frames}
        if self.stereo:
            out.update(self.pairer.counters.as_dict())
        return out
