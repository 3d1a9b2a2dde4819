"""The device model: every fact about a device that follows from its profile, in one place.

Sensors (which produce frames) and pipelines (which turn a stack of them into depth) both need to
know how a stack is laid out, what the full scale of a sample is, which dot pattern the projector
shows, how long a source-code slot lasts and which curtain a scan sweeps.  They read it here, from
`DeviceModel.from_profile(profile)`, so that neither imports the other::

    model = DeviceModel.from_profile(profile)
    model.pipeline        # "columns" | "dots" | "event-dots" | "curtain"  (profile ``sensor.pipeline``)
    model.layout          # "stack" (coded columns) | "slots" (one projector frame in the L slots)
    model.schedule        # int64 (frames_per_stack,) projector frame ids of one stack, capture order
    model.n_code_frames   # n (1 without a column code);  model.source_length: L (1 without a source code)
    model.full_scale      # float, largest sample value: 2**camera.bits - 1
    model.slot_us         # int, one source-code slot in microseconds (1e6 / projector.rate_hz)
    model.dot_pattern()   # bool (projector.height, projector.width): the dot projector's pattern
    model.curtain_disparity(stack)  # int pixels: the curtain scanned in ``stack``
    frame_ids(profile.zenoh.device)  # REP 103 / 105 frame names: <name>_link, _optical_frame, ...

Projector frame ids (the wire convention of every backend, recording and assembler) pack three
facts into one non-negative int::

    id = (edc_round << 16) | (slot << 8) | base

    base       0..n-1  code frame i;  WHITE (0xFE) calibration all-on;  BLACK (0xFF) all-off
    slot       0..L-1  source-code chip (0 when the profile has no source code)
    edc_round  0 = full pattern, r >= 1 = frames masked by adaptive round r

Stack layouts: ``"stack"`` (n code frames, WHITE, BLACK, each in L slots: `stack_schedule`) and
``"slots"`` (projector frame 0 in the L slots of the source code: `slot_schedule`).

Pipeline kinds (`PIPELINES`): each names the projector kind it reads and the class that processes
its stacks (``"module:Class"``, resolved by `edge.runtime.pipelines.make_pipeline`, so this module
imports nothing above it).  Adding a pipeline kind = its module in ``edge/runtime/`` + one line in
`PIPELINES`.

This module takes a profile by duck typing (an `edge.profiles.Profile` or anything with the same
attributes) and imports only `edge.codes` and `edge.source` (lazily).
"""

from __future__ import annotations

import functools
import re
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from edge.capture import dtype_for_bits
from edge.capture import full_scale as capture_full_scale

#: base id of the white (projector fully on) calibration frame
WHITE = 0xFE
#: base id of the black (projector fully off) calibration frame
BLACK = 0xFF
#: largest number of code frames an id can address (bases 0..MAX_CODE_FRAMES-1)
MAX_CODE_FRAMES = 0xFE
MAX_SLOTS = 0x100
MAX_EDC_ROUND = 0x7FFF


class ProjectorFrame(NamedTuple):
    """A decoded projector frame id (see module docstring)."""

    base: int
    slot: int
    edc_round: int

    @property
    def is_white(self) -> bool:
        return self.base == WHITE

    @property
    def is_black(self) -> bool:
        return self.base == BLACK

    @property
    def code_index(self) -> int:
        """Code frame index 0..n-1, or -1 for a calibration frame."""
        return self.base if self.base < MAX_CODE_FRAMES else -1


def projector_frame_id(base: int, *, slot: int = 0, edc_round: int = 0) -> int:
    """Pack (base, slot, edc_round) into one projector frame id.

    base: code frame index 0..253, `WHITE` or `BLACK`; slot: 0..255; edc_round: 0..32767.
    """
    if not 0 <= base <= BLACK:
        raise ValueError(f"projector frame base must be a code frame 0..{MAX_CODE_FRAMES - 1}, WHITE or BLACK, got {base}")
    if not 0 <= slot < MAX_SLOTS:
        raise ValueError(f"source-code slot must be in 0..{MAX_SLOTS - 1}, got {slot}")
    if not 0 <= edc_round <= MAX_EDC_ROUND:
        raise ValueError(f"EDC round must be in 0..{MAX_EDC_ROUND}, got {edc_round}")
    return (int(edc_round) << 16) | (int(slot) << 8) | int(base)


def parse_projector_frame(frame_id: int) -> ProjectorFrame:
    """Inverse of `projector_frame_id`."""
    frame_id = int(frame_id)
    if frame_id < 0 or frame_id >> 16 > MAX_EDC_ROUND:
        raise ValueError(f"projector frame id must be in 0..{(MAX_EDC_ROUND << 16) | 0xFFFF}, got {frame_id}")
    return ProjectorFrame(frame_id & 0xFF, (frame_id >> 8) & 0xFF, frame_id >> 16)


def stack_schedule(n_code_frames: int, source_length: int = 1, *, edc_round: int = 0) -> np.ndarray:
    """Projector frame ids of one stack, in capture order: (n + 2) * L int64.

    Code frames 0..n-1, then WHITE, then BLACK; each expanded into ``source_length`` slots.
    """
    if not 1 <= n_code_frames <= MAX_CODE_FRAMES:
        raise ValueError(f"a stack needs 1..{MAX_CODE_FRAMES} code frames, got {n_code_frames}")
    if not 1 <= source_length <= MAX_SLOTS:
        raise ValueError(f"source code length must be in 1..{MAX_SLOTS}, got {source_length}")
    bases = list(range(n_code_frames)) + [WHITE, BLACK]
    return np.array(
        [projector_frame_id(b, slot=s, edc_round=edc_round) for b in bases for s in range(source_length)],
        dtype=np.int64,
    )


def slot_schedule(source_length: int = 1, *, edc_round: int = 0) -> np.ndarray:
    """Projector frame ids of a "slots" stack: projector frame 0 in slots 0..L-1, int64 (L,)."""
    if not 1 <= source_length <= MAX_SLOTS:
        raise ValueError(f"source code length must be in 1..{MAX_SLOTS}, got {source_length}")
    return np.array([projector_frame_id(0, slot=s, edc_round=edc_round) for s in range(source_length)],
                    dtype=np.int64)


LAYOUTS = ("stack", "slots")


def layout_schedule(layout: str, n_code_frames: int, source_length: int = 1) -> np.ndarray:
    """The schedule of a stack layout (see module docstring)."""
    if layout == "stack":
        return stack_schedule(n_code_frames, source_length)
    if layout == "slots":
        return slot_schedule(source_length)
    raise ValueError(f"stack layout must be one of {', '.join(LAYOUTS)}, got {layout!r}")



# -- pipeline kinds ------------------------------------------------------------------------------


class PipelineSpec(NamedTuple):
    """One pipeline kind: the ``projector.kind`` it reads and its class (``"module:Class"``)."""

    projector: str
    target: str


#: Pipeline kinds: coded column patterns, dot projector + frame camera, dot projector + event
#: sensor, light curtain.  One line per kind (see the module docstring).
PIPELINES: dict[str, PipelineSpec] = {
    "columns": PipelineSpec("columns", "edge.runtime.pipeline:DepthPipeline"),
    "dots": PipelineSpec("dots", "edge.runtime.dots:DotsPipeline"),
    "event-dots": PipelineSpec("dots", "edge.runtime.dots:EventDotsPipeline"),
    "curtain": PipelineSpec("line", "edge.runtime.curtain:CurtainPipeline"),
}


def default_pipeline(projector_kind: str, sensor_backend: str) -> str:
    """The pipeline kind of a profile that does not declare ``sensor.pipeline``: columns -> "columns",
    line -> "curtain", dots -> "event-dots" with an event sensor (``sensor.backend = "event"``), else "dots"."""
    if projector_kind == "columns":
        return "columns"
    if projector_kind == "line":
        return "curtain"
    return "event-dots" if sensor_backend == "event" else "dots"


def pipeline_kind(profile) -> str:
    """The profile's pipeline kind: ``sensor.pipeline``, or `default_pipeline` when it is ""."""
    declared = getattr(profile.sensor, "pipeline", "")
    return declared or default_pipeline(profile.projector.kind, profile.sensor.backend)


# -- dot projector -------------------------------------------------------------------------------

#: fraction of projector pixels that are dots
DOT_DENSITY = 0.12


def dot_pattern(profile) -> np.ndarray:
    """bool (projector.height, projector.width): the dot projector's pattern.

    Simulated devices draw it with `edge.source.dots.random_dots` (density `DOT_DENSITY`, seed
    ``sim.seed``); the pipelines use the same call as their block-matching reference.
    """
    from edge.source.dots import random_dots

    return random_dots(profile.projector.width, profile.projector.height, density=DOT_DENSITY,
                       seed=int(profile.sim.seed))


def check_dot_profile(profile) -> None:
    """The projector must be rectified with the camera at the same size (reference = projector pattern)."""
    p, c = profile.projector, profile.camera
    if (p.width, p.height) != (c.width, c.height):
        raise ValueError(f"profile {profile.name!r}: a dot projector must match the camera size for block "
                         f"matching, expected projector {c.width}x{c.height}, got {p.width}x{p.height}")


def slot_us(profile) -> int:
    """Slot (= time slice) length in whole microseconds: 1e6 / projector.rate_hz."""
    return int(round(1e6 / profile.projector.rate_hz))


# -- light curtain -------------------------------------------------------------------------------

#: curtains per sweep of the disparity band
CURTAINS = 8


def curtain_disparities(profile) -> np.ndarray:
    """int64 (CURTAINS,) curtain disparities, near (max_disparity) to far (min_disparity)."""
    d = profile.decoder
    return np.rint(np.linspace(d.max_disparity, d.min_disparity, CURTAINS)).astype(np.int64)


def curtain_disparity(profile, stack: int) -> int:
    """Disparity (pixels) of the curtain scanned in ``stack``: the sweep repeats every CURTAINS stacks."""
    return int(curtain_disparities(profile)[int(stack) % CURTAINS])


# -- the model -----------------------------------------------------------------------------------


def stack_layout(profile) -> tuple[int, int]:
    """(n code frames, source-code length L) of a profile's stacks (n = 1 without a code)."""
    from edge.codes import get_code

    n = get_code(profile.code.name).n if profile.code.name else 1
    return n, max(1, len(profile.code.source))


def profile_layout(profile) -> str:
    """Stack layout of a profile: "stack" for column codes, else "slots"."""
    return "stack" if profile.projector.kind == "columns" else "slots"


def profile_schedule(profile) -> np.ndarray:
    """Projector frame ids of one stack of ``profile`` (see `layout_schedule`)."""
    n, L = stack_layout(profile)
    return layout_schedule(profile_layout(profile), n, L)


def full_scale(bits: int) -> float:
    """Largest sample value of a ``bits``-bit camera: 2**bits - 1 (255.0 for 8 bits), by the one
    full-scale rule `edge.capture.full_scale` of the camera's sample dtype."""
    return float(capture_full_scale(dtype_for_bits(bits), bits))


@dataclass(frozen=True, eq=False)
class DeviceModel:
    """The profile-derived facts of one device (see the module docstring).  Build with `from_profile`.

    pipeline: pipeline kind (a `PIPELINES` key); layout: "stack" | "slots"; n_code_frames: n;
    source_length: L; schedule: int64 (frames_per_stack,) projector frame ids (read-only);
    source: the source-code chips ("1" without a source code); full_scale: 2**bits - 1;
    bits: camera bits per sample; width, height: camera pixels; slot_us: slot length (us);
    profile: the profile it was built from.
    """

    profile: object
    pipeline: str
    layout: str
    n_code_frames: int
    source_length: int
    schedule: np.ndarray
    source: str
    bits: int
    full_scale: float
    width: int
    height: int
    slot_us: int

    @classmethod
    def from_profile(cls, profile) -> "DeviceModel":
        n, L = stack_layout(profile)
        layout = profile_layout(profile)
        schedule = layout_schedule(layout, n, L)
        schedule.flags.writeable = False
        cam = profile.camera
        return cls(profile=profile, pipeline=pipeline_kind(profile), layout=layout, n_code_frames=n,
                   source_length=L, schedule=schedule, source=profile.code.source or "1", bits=int(cam.bits),
                   full_scale=full_scale(cam.bits), width=int(cam.width), height=int(cam.height),
                   slot_us=slot_us(profile))

    @property
    def frames_per_stack(self) -> int:
        return int(self.schedule.size)

    @property
    def spec(self) -> PipelineSpec:
        """The `PIPELINES` entry of this device's pipeline kind."""
        return PIPELINES[self.pipeline]

    @functools.cached_property
    def _dots(self) -> np.ndarray:
        pattern = dot_pattern(self.profile)
        pattern.flags.writeable = False
        return pattern

    def dot_pattern(self) -> np.ndarray:
        """bool (projector.height, projector.width) read-only: the dot pattern (`dot_pattern`), drawn once."""
        return self._dots

    def curtain_disparity(self, stack: int) -> int:
        """Disparity (pixels) of the curtain scanned in ``stack`` (`curtain_disparity`)."""
        return curtain_disparity(self.profile, stack)


# -- names -----------------------------------------------------------------------------------


def ros_name(name: str) -> str:
    """A ROS-legal name token from an edge device / profile name: every character outside
    [A-Za-z0-9_] becomes '_', and a leading digit gets a '_' prefix (``sim-dlp`` -> ``sim_dlp``)."""
    out = re.sub(r"[^A-Za-z0-9_]", "_", str(name))
    if not out:
        raise ValueError("expected a non-empty name for a ROS node / topic")
    return "_" + out if out[0].isdigit() else out


def frame_ids(device: str) -> dict[str, str]:
    """REP 103 / 105 frame ids of one device: ``base`` ``<name>_link`` (body: x forward, y left,
    z up), ``optical`` ``<name>_optical_frame`` (the camera: depth, confidence, points,
    calibration) and ``projector`` ``<name>_projector_optical_frame`` (the projector, or the
    right camera of a stereo profile: the optical frame moved by +baseline_m along x)."""
    n = ros_name(device)
    return {"base": f"{n}_link", "optical": f"{n}_optical_frame", "projector": f"{n}_projector_optical_frame"}
