"""What every pipeline returns (`DepthResult`) and the masked-capture callable it may be given.

Its own module so that the pipelines (`edge.runtime.pipeline`, `edge.runtime.dots`,
`edge.runtime.curtain`) and the sinks share it without importing each other.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from ..sensors.base import Frame

#: A callable that captures masked frames for the EDC loop: (stack id, round, projector rows (m, Wp)) -> frames
MaskedCaptureFn = Callable[[int, int, np.ndarray], list[Frame]]


@dataclass(frozen=True, eq=False)
class DepthResult:
    """One depth map and what produced it.

    depth_mm: (H, W) uint16 millimetres, 0 = invalid.  confidence: (H, W) uint8, 255 = most
    confident, 0 where invalid.  column: (H, W) int32 decoded codeword index, -1 invalid.
    stack / sequence: stack id and sequence number of its first frame; timestamp_ns: sensor
    time of its last frame; received_ns: host time (time.time_ns) the last frame arrived;
    decode_s: seconds spent in `process`; edc_rounds: adaptive rounds run; extra_frames: frames
    captured by those rounds (in capture order, so they can be recorded and replayed); stats:
    per-stack counters that the service sums into its status (e.g. ``events_out_of_order``);
    edc_round_ms: decode milliseconds of each EDC round (round 1 = the check of the stack);
    edc_capture_ms: milliseconds waited for each masked round's frames; stack_frames: camera
    frames of the stack itself.  error: (H, W) float32 the decoder's estimated probability that
    the published column is wrong (`edge.decode.Decoded.error`), NaN where there is no depth or no
    estimate (`edge.runtime.depth.error_image`); None when the pipeline estimates none (the
    "confidence" validity rule, the dots / line pipelines).  noise: the decoder's noise model of
    this stack under the "error" rule, (a, beta, fitted): variance ``a + beta * I`` in normalised
    units, fitted False where too few pixels could be fitted and the profile's sigmas were used
    (`edge.decode.posterior.fit_noise`); None otherwise.  profile: the `edge.profiles.Profile`
    whose pipeline decoded this stack (set by the service; None outside it): a recording marks
    the stack where it differs from the one before (a live change), and a replay switches there.
    """

    stack: int
    sequence: int
    timestamp_ns: int
    received_ns: int
    depth_mm: np.ndarray
    confidence: np.ndarray
    column: np.ndarray
    decode_s: float = 0.0
    edc_rounds: int = 0
    extra_frames: tuple[Frame, ...] = field(default=())
    stats: dict[str, int] = field(default_factory=dict)
    geometry: Any = None  # the geometry the depth was computed with (set by the service; None = profile's)
    edc_round_ms: tuple[float, ...] = ()
    edc_capture_ms: tuple[float, ...] = ()
    stack_frames: int = 0
    error: np.ndarray | None = None
    noise: tuple[float, float, bool] | None = None
    profile: Any = None

    @property
    def frames_per_depth_map(self) -> int:
        """Camera frames this depth map used: the stack's plus the EDC rounds' masked frames."""
        return int(self.stack_frames) + len(self.extra_frames)

    @property
    def valid_fraction(self) -> float:
        return float(np.count_nonzero(self.depth_mm)) / max(1, self.depth_mm.size)

    def median_depth_mm(self) -> float:
        d = self.depth_mm[self.depth_mm > 0]
        return float(np.median(d)) if d.size else float("nan")
