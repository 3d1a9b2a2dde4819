"""Typed, validated firmware-profile settings.

A profile is a frozen `Profile` made of one frozen dataclass per TOML table. Every field carries
its constraints in ``dataclasses.field(metadata=...)``; `build_profile` walks the nested dict, checks
unknown keys, types and ranges, then runs the cross-field checks in `_check_profile`, and raises
ONE `ProfileError` naming the source, the dotted key and the reason.

TOML layout (every table and key; ``=`` gives the default, no default = required)::

    name = "sim-dlp"                      # profile name: [a-z0-9][a-z0-9_-]*
    description = ""

    [sensor]
    backend = "sim"                       # sim | replay | oak | event
    replay_path = ""                      # MCAP file for the replay backend ("" = given on the CLI)
    replay_speed = "recorded"             # recorded | max
    pipeline = ""                         # columns | dots | event-dots | curtain (edge.device.PIPELINES);
                                          # "" = from projector.kind: columns -> columns, line -> curtain,
                                          # dots -> event-dots with backend "event", else dots

    [projector]
    kind = "columns"                      # columns (DLP code patterns) | dots | line
    width = 1024                          # projector columns
    height = 768
    rate_hz = 120.0                       # frames per second (>= 1)
    stripe = 1                            # projector columns per codeword (architecture.md); <= width / 2

    [camera]
    width = 640                           # >= 2 (also height)
    height = 480
    rate_hz = 120.0                       # >= 1 frame per second
    bits = 8                              # 8 | 10 | 12 | 16 (uint8 for 8, uint16 otherwise)
    exposure_us = 8000.0                  # <= 1e6 / rate_hz
    sigma_r = 0.004                       # read noise, std dev on the [0, 1] intensity scale (0..1)
    sigma_s = 0.015                       # shot-noise factor: variance = sigma_r**2 + sigma_s**2 * I (0..1;
                                          # the bound: edge.capture.MAX_SIGMA)

    [code]
    name = "ecc-22-10"                    # edge.codes.get_code name; "" only for dots / line projectors
    source = ""                           # light-source code bit string ("" = none), e.g. "1101";
                                          # a stack (frames x pixels) must fit STACK_PIXEL_BUDGET

    [decoder]                             # every key but the band defaults to the library's
                                          # edge.decode.DEFAULT_SETTINGS (edge.decode.settings)
    method = "soft"                       # columns: edge.decode.METHODS (soft | hard | list | median |
                                          # list+median); dots: block-match; line: curtain
    validity = "auto"                     # auto | error | confidence: "auto" = the error-probability
                                          # rule for the soft methods without inverse frames
    max_error = 0.01                      # "error" rule: valid where P(wrong column) < max_error
    levels = "auto"                       # auto | calibration | refit: "auto" = split per pixel
                                          # (error rule, binary codes), else calibration
    min_contrast = 0.02                   # "confidence" rule: white - black floor (0..1 scale, < 1);
                                          # dots / line: matched-filter minimum amplitude
    min_confidence = 0.3                  # "confidence" rule: (d2 - d1) / d2 floor (0..1, < 1);
                                          # dots / line: matched-filter correlation threshold
    metric = "ml"                         # also t_low = 0.05, t_high = 0.3, spatial_check = true,
    backend = "cpu"                       # (the "confidence" rule's spatial check); cpu | cuda | auto
    min_disparity = -176                  # disparity band, pixels (architecture.md convention)
    max_disparity = -64

    [edc]
    rounds = 0                            # adaptive re-projection rounds (0 = EDC loop off)

    [geometry]                            # rectified, Middlebury convention (architecture.md); the depth
                                          # over the disparity band must overlap 1..65535 mm
    baseline_m = 0.08
    focal_px = 560.0
    cx_camera = 320.0
    cx_projector = 512.0
    cy = 240.0

    [zenoh]
    prefix = "sl"                         # keys are <prefix>/<device>/depth etc.
    device = "sim-dlp"                    # default: the profile name
    mode = "peer"                         # peer | client | router
    listen = ["tcp/127.0.0.1:7451"]
    connect = []
    multicast_scouting = false
    status_period_s = 1.0                 # >= 0.05 s
    connect_timeout_s = 0.0               # client: wait up to S s at start-up for a router (0: fail at once)
    config_writes = false                 # accept config updates on <prefix>/<device>/config (reads always)
    access_control = ""                   # zenoh ACL: the JSON object of zenoh's "access_control" config,
                                          # required when config_writes is on beyond loopback (README)

    [recording]
    chunk_size = 4194304                  # bytes of uncompressed messages per MCAP chunk
    compression = "zstd"                  # zstd | lz4 | none
    raw = true                            # record raw camera frames
    outputs = true                        # record depth and confidence

    [points]                              # point clouds (edge.runtime.depth.depth_to_points)
    stride = 2                            # every stride-th pixel row and column (1 = all)
    publish = true                        # live: sl/<device>/points, ROS PointCloud2, Foxglove
    record = true                         # MCAP: /<device>/points (foxglove.PointCloud)

    [oak]                                 # OAK-D Pro backend (edge.sensors.oak); live-settable
    dot_intensity = 0.8                   # IR dot projector on its source-code slots, 0..1
    flood_intensity = 0.0                 # IR flood LED on WHITE frames, 0..1
    lead_frames = 2                       # emitter command this many frames ahead (latency)
    emitter_control = "script"            # script (on-device Script node per frame) | host

    [ros]                                 # ROS 2 over rmw_zenoh (edge.io.ros_sink)
    enabled = false                       # or `edge run --ros`; domain from ROS_DOMAIN_ID (default 0)
    router = "tcp/localhost:7447"         # the rmw_zenohd router to connect to
    node = ""                             # ROS node name ("" = device name with '-' -> '_')

    [room]                                # several devices in one room (edge.io.room, README)
    name = ""                             # room name ("" = alone); `edge run --room NAME`
    family_size = 4                       # codes in the room's source-code family = most devices
    code_length = 8                       # L of the family's codes (frame rate / L)
    settle_s = 0.5                        # seconds to wait for the other members' claims

    [sim]
    scene = "steps"                       # edge.sim.make_scene name (edge.sim.scene_names())
    seed = 0
    ambient = 0.2                         # ambient light level (0..1 scale)
    projector = 0.6                       # projector light level (0..1 scale)
"""

from __future__ import annotations

import dataclasses
import math
import re
import typing
from dataclasses import dataclass, field
from typing import Any, Mapping

from edge.capture import MAX_SIGMA
from edge.decode.settings import DEFAULT_SETTINGS as _LIB
from edge.device import PIPELINES

__all__ = [
    "ProfileError",
    "Profile",
    "SensorSettings",
    "ProjectorSettings",
    "CameraSettings",
    "CodeSettings",
    "DecoderSettings",
    "EdcSettings",
    "GeometrySettings",
    "ZenohSettings",
    "RecordingSettings",
    "SimSettings",
    "PointsSettings",
    "RosSettings",
    "OakSettings",
    "RoomSettings",
    "build_profile",
    "profile_to_dict",
    "DECODER_METHODS",
    "SENSOR_BACKENDS",
    "decoder_methods",
    "STACK_PIXEL_BUDGET",
]

SENSOR_BACKENDS = ("sim", "replay", "oak", "event")
PROJECTOR_KINDS = ("columns", "dots", "line")
ZENOH_MODES = ("peer", "client", "router")
COMPRESSIONS = ("zstd", "lz4", "none")
CAMERA_BITS = (8, 10, 12, 16)
#: decoder.method of the non-column pipelines, by projector.kind (columns: `edge.decode.METHODS`)
PIPELINE_METHODS = {"dots": ("block-match",), "line": ("curtain",)}
#: Frames x pixels of one stack at most (about 10 bytes of working memory each: ~1.3 GB).
STACK_PIXEL_BUDGET = 1 << 27
#: Camera / projector frame rate at least (Hz): slower, one stack takes minutes to hours.
MIN_RATE_HZ = 1.0
#: The depth output is uint16 millimetres, 0 = invalid.
DEPTH_RANGE_MM = (1.0, 65535.0)


def decoder_methods(projector_kind: str | None = None) -> tuple[str, ...]:
    """The decoder.method values a ``projector_kind`` profile may use (all of them for None).

    Column codes use `edge.decode.METHODS` (the decoder's own list, the one source); dot projectors
    are block-matched and a line projector is decoded by the light-curtain pipeline."""
    from edge.decode.decoder import METHODS

    if projector_kind == "columns":
        return tuple(METHODS)
    if projector_kind is not None:
        return PIPELINE_METHODS.get(projector_kind, ())
    return tuple(METHODS) + tuple(m for ms in PIPELINE_METHODS.values() for m in ms)


def __getattr__(name: str) -> Any:  # DECODER_METHODS is derived lazily (edge.decode imports numba)
    if name == "DECODER_METHODS":
        return decoder_methods()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

_NAME = r"[a-z0-9][a-z0-9_-]*"
_KEY_CHUNK = r"[A-Za-z0-9_-]+"
_ENDPOINT = r"(tcp|udp|tls|quic|ws|unixsock-stream)/\S+"


class ProfileError(ValueError):
    """A profile failed validation: ``<source>: <dotted.key>: <reason>`` on one line."""

    def __init__(self, source: str, key: str, reason: str):
        self.source = source
        self.key = key
        self.reason = reason
        where = f"{source}: {key}: " if key else f"{source}: "
        super().__init__(where + reason)


def _f(default: Any = dataclasses.MISSING, *, lo: float | None = None, hi: float | None = None,
       lo_open: bool = False, hi_open: bool = False, choices: tuple | None = None,
       pattern: str | None = None) -> Any:
    """A dataclass field with validation metadata (range, allowed values, regex)."""
    meta = {"lo": lo, "hi": hi, "lo_open": lo_open, "hi_open": hi_open, "choices": choices, "pattern": pattern}
    if isinstance(default, (list, tuple)):
        value = tuple(default)
        return field(default_factory=lambda: value, metadata=meta)
    return field(default=default, metadata=meta)


@dataclass(frozen=True)
class SensorSettings:
    backend: str = _f("sim", choices=SENSOR_BACKENDS)
    replay_path: str = _f("")
    replay_speed: str = _f("recorded", choices=("recorded", "max"))
    pipeline: str = _f("")  # a kind of edge.device.PIPELINES (checked in _check_pipeline); "" = default_pipeline


@dataclass(frozen=True)
class ProjectorSettings:
    width: int = _f(lo=1, hi=65536)
    height: int = _f(lo=1, hi=65536)
    rate_hz: float = _f(lo=0.0, hi=1e6, lo_open=True)
    kind: str = _f("columns", choices=PROJECTOR_KINDS)
    stripe: int = _f(1, lo=1, hi=4096)


@dataclass(frozen=True)
class CameraSettings:
    width: int = _f(lo=2, hi=65536)
    height: int = _f(lo=2, hi=65536)
    rate_hz: float = _f(lo=0.0, hi=1e6, lo_open=True)
    exposure_us: float = _f(lo=0.0, lo_open=True)
    bits: int = _f(8, choices=CAMERA_BITS)
    sigma_r: float = _f(0.0, lo=0.0, hi=MAX_SIGMA)  # the decoder's bound (0: noiseless, floored in from_profile)
    sigma_s: float = _f(0.0, lo=0.0, hi=MAX_SIGMA)


@dataclass(frozen=True)
class CodeSettings:
    name: str = _f()
    source: str = _f("", pattern=r"[01]{0,64}")


@dataclass(frozen=True)
class DecoderSettings:
    """The ``[decoder]`` table.  Every key but the disparity band is a field of
    `edge.decode.settings.DecodeSettings` and defaults to the library's `DEFAULT_SETTINGS` (one
    source of defaults: a profile that does not set a key decodes as `edge.decode.decode` does);
    `edge.decode.settings.from_profile` is the one mapping and checks the values.  The dots / line
    pipelines read ``min_contrast`` / ``min_confidence`` as their matched filter's amplitude and
    correlation thresholds (`edge.runtime.dots`, `edge.runtime.curtain`): their profiles set both."""

    min_disparity: int = _f(lo=-65536, hi=65536)
    max_disparity: int = _f(lo=-65536, hi=65536)
    method: str = _f(_LIB.method)  # checked against the pipeline kind in _check_profile
    min_contrast: float = _f(_LIB.min_contrast, lo=0.0, hi=1.0, hi_open=True)
    min_confidence: float = _f(_LIB.min_confidence, lo=0.0, hi=1.0, hi_open=True)
    metric: str = _f(_LIB.metric)
    levels: str = _f(_LIB.levels)
    t_low: float = _f(_LIB.t_low, lo=0.0, hi=1.0)
    t_high: float = _f(_LIB.t_high, lo=0.0, hi=1.0)
    spatial_check: bool = _f(_LIB.spatial_check)
    validity: str = _f(_LIB.validity)
    max_error: float = _f(_LIB.max_error, lo=0.0, hi=1.0, lo_open=True, hi_open=True)
    backend: str = _f(_LIB.backend)


@dataclass(frozen=True)
class EdcSettings:
    rounds: int = _f(0, lo=0, hi=16)


@dataclass(frozen=True)
class GeometrySettings:
    baseline_m: float = _f(lo=0.0, hi=100.0, lo_open=True)
    focal_px: float = _f(lo=0.0, hi=1e6, lo_open=True)
    cx_camera: float = _f(lo=-1e6, hi=1e6)
    cx_projector: float = _f(lo=-1e6, hi=1e6)
    cy: float = _f(lo=-1e6, hi=1e6)

    @property
    def doffs(self) -> float:
        """``cx_projector - cx_camera`` in pixels (depth = focal_px * baseline_m / (d + doffs))."""
        return self.cx_projector - self.cx_camera


@dataclass(frozen=True)
class ZenohSettings:
    device: str = _f(pattern=_KEY_CHUNK)
    prefix: str = _f("sl", pattern=_KEY_CHUNK + r"(/" + _KEY_CHUNK + r")*")
    mode: str = _f("peer", choices=ZENOH_MODES)
    listen: tuple[str, ...] = _f(("tcp/127.0.0.1:7451",), pattern=_ENDPOINT)
    connect: tuple[str, ...] = _f((), pattern=_ENDPOINT)
    multicast_scouting: bool = _f(False)
    status_period_s: float = _f(1.0, lo=0.05, hi=3600.0)
    connect_timeout_s: float = _f(0.0, lo=0.0, hi=3600.0)
    config_writes: bool = _f(False)
    access_control: str = _f("")

    def key(self, leaf: str) -> str:
        """``<prefix>/<device>/<leaf>``, e.g. ``sl/sim-dlp/depth``."""
        return f"{self.prefix}/{self.device}/{leaf}"


@dataclass(frozen=True)
class RecordingSettings:
    chunk_size: int = _f(4 * 1024 * 1024, lo=4096, hi=1 << 30)
    compression: str = _f("zstd", choices=COMPRESSIONS)
    raw: bool = _f(True)
    outputs: bool = _f(True)


@dataclass(frozen=True)
class PointsSettings:
    stride: int = _f(2, lo=1, hi=64)
    publish: bool = _f(True)
    record: bool = _f(True)


@dataclass(frozen=True)
class OakSettings:
    dot_intensity: float = _f(0.8, lo=0.0, hi=1.0)
    flood_intensity: float = _f(0.0, lo=0.0, hi=1.0)
    lead_frames: int = _f(2, lo=0, hi=64)
    emitter_control: str = _f("script", choices=("script", "host"))


@dataclass(frozen=True)
class RosSettings:
    enabled: bool = _f(False)
    router: str = _f("tcp/localhost:7447", pattern=_ENDPOINT)
    node: str = _f("", pattern=r"([A-Za-z_][A-Za-z0-9_]*)?")


@dataclass(frozen=True)
class RoomSettings:
    name: str = _f("", pattern=r"(" + _KEY_CHUNK + r")?")
    family_size: int = _f(4, lo=1, hi=16)
    code_length: int = _f(8, lo=4, hi=16)
    settle_s: float = _f(0.5, lo=0.0, hi=30.0)


@dataclass(frozen=True)
class SimSettings:
    scene: str = _f("steps", pattern=_NAME)
    seed: int = _f(0, lo=0, hi=2**63 - 1)
    ambient: float = _f(0.2, lo=0.0, hi=100.0)
    projector: float = _f(0.6, lo=0.0, hi=100.0)


@dataclass(frozen=True)
class Profile:
    """One device's firmware profile (see the module docstring for the TOML layout).

    ``source`` is where it came from (a file path or ``"<dict>"``); it is not part of the
    settings and is not written by `profile_to_dict`.
    """

    name: str = _f(pattern=_NAME)
    projector: ProjectorSettings = _f()
    camera: CameraSettings = _f()
    code: CodeSettings = _f()
    decoder: DecoderSettings = _f()
    geometry: GeometrySettings = _f()
    zenoh: ZenohSettings = _f()
    description: str = _f("")
    sensor: SensorSettings = _f(SensorSettings())
    edc: EdcSettings = _f(EdcSettings())
    recording: RecordingSettings = _f(RecordingSettings())
    sim: SimSettings = _f(SimSettings())
    points: PointsSettings = _f(PointsSettings())
    ros: RosSettings = _f(RosSettings())
    oak: OakSettings = _f(OakSettings())
    room: RoomSettings = _f(RoomSettings())
    source: str = field(default="<dict>", compare=False, metadata={"internal": True})


# ---------------------------------------------------------------------------------------------
# validation engine


def _type_name(value: Any) -> str:
    return {bool: "boolean", int: "integer", float: "number", str: "string",
            list: "array", tuple: "array", dict: "table"}.get(type(value), type(value).__name__)


def _describe(tp: Any) -> str:
    return {int: "an integer", float: "a number", str: "a string", bool: "true or false"}.get(
        tp, "an array of strings")


def _check_scalar(tp: Any, value: Any, meta: Mapping[str, Any], source: str, key: str) -> Any:
    if tp is bool:
        ok = isinstance(value, bool)
    elif tp is int:
        ok = isinstance(value, int) and not isinstance(value, bool)
    elif tp is float:
        ok = isinstance(value, (int, float)) and not isinstance(value, bool)
        if ok:
            value = float(value)
            if not math.isfinite(value):
                raise ProfileError(source, key, f"expected a finite number, got {value!r}")
    else:
        ok = isinstance(value, str)
    if not ok:
        raise ProfileError(source, key, f"expected {_describe(tp)}, got {_type_name(value)} {value!r}")
    choices = meta.get("choices")
    if choices is not None and value not in choices:
        raise ProfileError(source, key, f"expected one of {', '.join(map(repr, choices))}, got {value!r}")
    pattern = meta.get("pattern")
    if pattern is not None and not re.fullmatch(pattern, value):
        raise ProfileError(source, key, f"expected a string matching {pattern!r}, got {value!r}")
    lo, hi = meta.get("lo"), meta.get("hi")
    below = lo is not None and (value <= lo if meta.get("lo_open") else value < lo)
    above = hi is not None and (value >= hi if meta.get("hi_open") else value > hi)
    if below or above:
        raise ProfileError(source, key, f"expected a value {_range_text(meta)}, got {value!r}")
    return value


def _range_text(meta: Mapping[str, Any]) -> str:
    """The allowed range of a field's metadata, both ends where it has both: ``>= 0 and <= 1``
    (integer ends written out, float ends as ``%g``)."""
    ends = []
    for end, open_, ops in (("lo", "lo_open", (">", ">=")), ("hi", "hi_open", ("<", "<="))):
        v = meta.get(end)
        if v is not None:
            ends.append(f"{ops[0] if meta.get(open_) else ops[1]} {v if isinstance(v, int) else format(v, 'g')}")
    return " and ".join(ends)


def _build(cls: type, data: Any, source: str, prefix: str) -> Any:
    if not isinstance(data, Mapping):
        raise ProfileError(source, prefix or "<root>", f"expected a table, got {_type_name(data)} {data!r}")
    hints = typing.get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls) if not f.metadata.get("internal")}
    unknown = [k for k in data if k not in fields]
    if unknown:
        key = f"{prefix}.{unknown[0]}" if prefix else str(unknown[0])
        raise ProfileError(source, key, f"unknown key; valid keys here: {', '.join(fields)}")
    kwargs: dict[str, Any] = {}
    for name, f in fields.items():
        key = f"{prefix}.{name}" if prefix else name
        tp = hints[name]
        if name not in data:
            if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
                what = "table" if dataclasses.is_dataclass(tp) else "key"
                raise ProfileError(source, key, f"missing required {what}")
            continue
        value = data[name]
        if dataclasses.is_dataclass(tp):
            kwargs[name] = _build(tp, value, source, key)
        elif typing.get_origin(tp) is tuple:
            if not isinstance(value, (list, tuple)):
                raise ProfileError(source, key, f"expected an array of strings, got {_type_name(value)} {value!r}")
            kwargs[name] = tuple(_check_scalar(str, v, f.metadata, source, f"{key}[{i}]")
                                 for i, v in enumerate(value))
        else:
            kwargs[name] = _check_scalar(tp, value, f.metadata, source, key)
    return cls(**kwargs)


def _check_profile(p: Profile, source: str) -> None:
    """Cross-field checks; each failure names the key it blames."""
    from edge.codes import get_code

    if p.code.name:
        try:
            code = get_code(p.code.name)
        except ValueError as exc:
            raise ProfileError(source, "code.name", str(exc)) from None
        if p.projector.kind == "columns":
            rows = code.codebook.shape[0]
            if p.projector.width > rows * p.projector.stripe:
                raise ProfileError(
                    source, "projector.width",
                    f"expected <= {rows * p.projector.stripe} columns ({rows} codewords of "
                    f"{p.code.name} x stripe {p.projector.stripe}), got {p.projector.width}")
    elif p.projector.kind == "columns":
        raise ProfileError(source, "code.name", "expected a code name for a 'columns' projector, got ''")
    if p.code.source and "1" not in p.code.source:
        raise ProfileError(source, "code.source", f"expected a bit string with at least one '1', got {p.code.source!r}")
    if len(p.code.source) > 1 and "0" not in p.code.source:
        raise ProfileError(source, "code.source", f"expected a bit string with at least one '0' (a source that is "
                           f"never off is no code: use '' for none), got {p.code.source!r}")
    if p.decoder.min_disparity > p.decoder.max_disparity:
        raise ProfileError(source, "decoder.max_disparity",
                           f"expected >= decoder.min_disparity ({p.decoder.min_disparity}), got {p.decoder.max_disparity}")
    doffs = p.geometry.doffs
    if p.decoder.min_disparity + doffs <= 0:
        raise ProfileError(
            source, "decoder.min_disparity",
            f"expected min_disparity + doffs > 0 so depth is finite over the band "
            f"(doffs = cx_projector - cx_camera = {doffs:g}), got {p.decoder.min_disparity}")
    _check_pipeline(p, source)
    period_us = 1e6 / p.camera.rate_hz
    if p.camera.exposure_us > period_us:
        raise ProfileError(source, "camera.exposure_us",
                           f"expected <= the frame period 1e6 / rate_hz = {period_us:g}, got {p.camera.exposure_us:g}")
    if p.zenoh.mode == "client" and not p.zenoh.connect:
        raise ProfileError(source, "zenoh.connect", "expected at least one endpoint in client mode, got []")
    _check_access(p.zenoh, source)


def _check_edc(p: Profile, source: str, kind: str) -> None:
    """``edc.rounds > 0`` needs what the adaptive rounds work with (`edge.edc`): a column projector
    (rounds re-project columns) and a code that detects errors, i.e. a binary code with d_min >= 2
    (a pixel passes where its hard-decision word is a codeword; with d_min = 1 every word is one,
    so nothing is ever checked) and at most `edge.codes.words.MAX_TABLE_BITS` frames (the
    membership look-up).  It was accepted, then ignored by the other pipelines or refused at
    start, or, with d_min = 1, published every pixel as verified."""
    if p.edc.rounds <= 0:
        return
    if kind != "columns":
        raise ProfileError(source, "edc.rounds", f"expected 0 for a {kind!r} projector (adaptive EDC rounds "
                                                 f"re-project the columns of a column code), got {p.edc.rounds}")
    from edge.codes import get_code
    from edge.codes.words import MAX_TABLE_BITS

    code = get_code(p.code.name)
    why = ("it is not binary" if code.q != 2 else
           f"it has {code.n} frames, more than the {MAX_TABLE_BITS} the look-up holds" if code.n > MAX_TABLE_BITS else
           "its d_min is 1: every word is a codeword, so no error is ever detected" if code.d_min < 2 else "")
    if why:
        raise ProfileError(source, "edc.rounds", f"expected 0 with code {code.name!r}: EDC needs a binary code of at "
                                                 f"most {MAX_TABLE_BITS} frames with d_min >= 2, and {why}; "
                                                 f"got {p.edc.rounds}")


def _check_pipeline(p: Profile, source: str) -> None:
    """Settings that validate one by one but make a pipeline that fails or yields no valid depth."""
    from edge.codes import get_code

    kind = p.projector.kind
    declared = p.sensor.pipeline
    if declared and declared not in PIPELINES:  # the registry, read now: a kind added there is valid here
        raise ProfileError(source, "sensor.pipeline",
                           f"expected one of '', {', '.join(map(repr, PIPELINES))}, got {declared!r}")
    if declared and PIPELINES[declared].projector != kind:
        raise ProfileError(source, "sensor.pipeline",
                           f"expected a pipeline that reads a {kind!r} projector "
                           f"({', '.join(repr(k) for k, s in PIPELINES.items() if s.projector == kind)}), got {declared!r}")
    methods = decoder_methods(kind)
    if p.decoder.method not in methods:
        raise ProfileError(source, "decoder.method",
                           f"expected one of {', '.join(map(repr, methods))} for a {kind!r} projector, "
                           f"got {p.decoder.method!r}")
    _check_edc(p, source, kind)
    d_lo, d_hi = p.decoder.min_disparity, p.decoder.max_disparity
    if kind == "columns":
        from edge.decode.settings import from_profile  # the decoder's own rules, one source

        try:
            from_profile(p)
        except ValueError as e:
            key, _, reason = str(e).partition(": ")
            raise ProfileError(source, f"decoder.{key.split(',')[0]}", reason) from None
        if 2 * p.projector.stripe > p.projector.width:
            raise ProfileError(source, "projector.stripe",
                               f"expected <= projector.width / 2 = {p.projector.width // 2} so the projector "
                               f"sends at least two codewords, got {p.projector.stripe}")
        first, last = -d_hi, p.camera.width - 1 - d_lo   # candidate columns x - max_d .. x - min_d
        if last < 0 or first > p.projector.width - 1:
            raise ProfileError(
                source, "decoder.min_disparity" if last < 0 else "decoder.max_disparity",
                f"expected a disparity band whose candidate columns (x - max_disparity .. x - min_disparity "
                f"= {first}..{last} over the camera) meet the projector's columns 0..{p.projector.width - 1}, "
                f"got min_disparity {d_lo}, max_disparity {d_hi}")
    g = p.geometry
    from edge.triangulation import depth_from_disparity

    near, far = (float(depth_from_disparity(d, g.focal_px, g.baseline_m, g.doffs, scale=1000.0))
                 for d in (d_hi, d_lo))   # mm at the band's ends (d + doffs > 0: checked above)
    lo_mm, hi_mm = DEPTH_RANGE_MM
    if near > hi_mm or far < lo_mm:
        raise ProfileError(
            source, "geometry.baseline_m",
            f"expected focal_px * baseline_m / (d + doffs) to reach the depth output range {lo_mm:g}..{hi_mm:g} mm "
            f"somewhere in the disparity band, got {near:.3g}..{far:.3g} mm (focal_px {g.focal_px:g}, "
            f"baseline_m {g.baseline_m:g}, doffs {g.doffs:g}, band {d_lo}..{d_hi})")
    n = get_code(p.code.name).n if p.code.name else 1
    frames = (n + 2) * max(1, len(p.code.source))
    for table in ("camera", "projector"):
        rate = getattr(p, table).rate_hz
        if rate < MIN_RATE_HZ:
            raise ProfileError(source, f"{table}.rate_hz",
                               f"expected >= {MIN_RATE_HZ:g} Hz (a stack of about {frames} frames would take "
                               f"{frames / rate:.3g} s), got {rate:g}")
    pixels = p.camera.width * p.camera.height
    if frames * pixels > STACK_PIXEL_BUDGET:
        raise ProfileError(
            source, "code.source" if p.code.source else "camera.width",
            f"expected a stack of at most {STACK_PIXEL_BUDGET} frame-pixels (about 10 bytes each while decoding), "
            f"got about {frames} frames of {p.camera.width}x{p.camera.height} = {frames * pixels}"
            + (f" with a {len(p.code.source)}-slot source code" if p.code.source else ""))
    if p.sim.projector <= p.decoder.min_contrast:
        raise ProfileError(source, "sim.projector",
                           f"expected > decoder.min_contrast ({p.decoder.min_contrast:g}): below it no pixel reaches "
                           f"the contrast the decoder asks for, got {p.sim.projector:g}")
    from edge.sim.scenes import scene_names

    names = scene_names()
    if p.sim.scene not in names:
        raise ProfileError(source, "sim.scene", f"expected one of {', '.join(names)}, got {p.sim.scene!r}")


_LOOPBACK = re.compile(r"(tcp|udp|tls|quic|ws)/(127\.\d+\.\d+\.\d+|localhost|\[::1\]):\d+([#?].*)?|unixsock-stream/.*")


def is_loopback(endpoint: str) -> bool:
    """True for a zenoh endpoint only this host can reach (127.x, localhost, [::1], unix socket)."""
    return bool(_LOOPBACK.fullmatch(endpoint))


def _check_access(z: "ZenohSettings", source: str) -> None:
    """Config writes beyond loopback need zenoh's own access control (ACL rules)."""
    import json

    if z.access_control:
        try:
            acl = json.loads(z.access_control)
        except ValueError as exc:
            raise ProfileError(source, "zenoh.access_control",
                               f"expected the JSON object of zenoh's access_control config, got invalid JSON ({exc})") from None
        if not isinstance(acl, dict):
            raise ProfileError(source, "zenoh.access_control",
                               f"expected the JSON object of zenoh's access_control config, got {_type_name(acl)}")
        import zenoh  # zenoh's own parser names a wrong field or type

        try:
            zenoh.Config().insert_json5("access_control", z.access_control)
        except Exception as exc:
            text = " ".join(str(exc).split())[:300]
            raise ProfileError(source, "zenoh.access_control", f"zenoh rejects the ACL config: {text}") from None
        return
    if not z.config_writes:
        return
    open_to = [e for e in (*z.listen, *z.connect) if not is_loopback(e)]
    if open_to or z.multicast_scouting:
        what = f"endpoint {open_to[0]}" if open_to else "multicast scouting"
        raise ProfileError(source, "zenoh.config_writes",
                           f"expected zenoh.access_control rules (zenoh ACL) when config writes are on and the "
                           f"session is reachable beyond loopback ({what}); see README 'Who may change the sensor'")


def build_profile(data: Mapping[str, Any], source: str = "<dict>") -> Profile:
    """Validate a nested dict (a parsed TOML file or JSON update) into a `Profile`.

    ``zenoh.device`` defaults to ``name``. Raises `ProfileError` on the first problem.
    """
    if isinstance(data, Mapping) and isinstance(data.get("zenoh"), Mapping) and "device" not in data["zenoh"]:
        if isinstance(data.get("name"), str):
            data = {**data, "zenoh": {**data["zenoh"], "device": data["name"]}}
    profile = _build(Profile, data, source, "")
    _check_profile(profile, source)
    return dataclasses.replace(profile, source=source)


def profile_to_dict(profile: Profile) -> dict[str, Any]:
    """Nested, JSON-able dict of every setting (tuples -> lists); `build_profile` inverts it."""

    def convert(obj: Any) -> Any:
        if dataclasses.is_dataclass(obj):
            return {f.name: convert(getattr(obj, f.name)) for f in dataclasses.fields(obj)
                    if not f.metadata.get("internal")}
        if isinstance(obj, tuple):
            return [convert(v) for v in obj]
        return obj

    return convert(profile)
