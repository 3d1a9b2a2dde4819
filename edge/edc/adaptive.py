"""Adaptive structured light driven by an error map (paper section 4; Xu & Aliaga 2009; Gupta 2011).

Round 1 projects the full pattern set plus a white (all on) and a black (all off) calibration
frame; every camera pixel is decoded and checked.  Pixels that pass are FIXED (never decoded
again).  Each following round lights only the projector pixels that may still be the source of a
failing camera pixel, re-captures, and decodes only the still-failing pixels.

Which projector pixels stay lit ("unresolved columns")
------------------------------------------------------
In the rectified geometry camera pixel (y, x) sees projector row y (the epipolar line), so the
mask is per projector pixel (row y, column c), not per whole column.  A failing pixel's true
column is unknown, so we cannot light "its" column.  We light every projector pixel of row y that
is NOT claimed by a passing camera pixel of row y: a claimed projector pixel already sends its
direct light to a camera pixel whose column is known, so (one projector pixel -> one camera pixel)
it cannot be the direct source of a failing pixel, and switching it off removes its indirect
contribution (inter-reflection, scattering) from everything else.  This is the rule of Xu &
Aliaga (2009) and Gupta et al. (2011): illuminate only the scene points not yet decoded correctly.
Two refinements:

* *guard*: a projector column can feed two camera pixels of one row (oblique surfaces, a camera
  finer than the projector); if one of them passed and its neighbour failed, the failing one would
  lose its direct light.  We therefore keep lit the columns claimed by passing pixels that are
  immediate row neighbours of a failing pixel (on a continuous surface the failing pixel's column
  lies between its neighbours' columns).  Cost: a few extra lit columns per failing run.
* rows without failing pixels are dark, and with a disparity band (min_disparity, max_disparity)
  only columns that some failing pixel of the row could see are lit.

A pixel also fails a round if its decoded column was dark in that round (it cannot have received
that code: free extra error detection), or if its white-minus-black contrast is below the shadow
floor ``min_contrast`` (no projector light; the all-dark word is the codeword of column 0).

Calibration frames in rounds 2+
-------------------------------
The binarisation threshold is ``(white + black) / 2``.  Switching columns off changes the indirect
light every pixel receives, so round 1's white frame no longer describes the "on" level: each
round r >= 2 captures ONE new calibration frame, the masked white (every lit projector pixel on).
The black frame (projector off: ambient only) does not depend on the mask in a static scene, so
round 1's black is reused.  Frames per round: n + 2, then n + 1 (17, 16, 16 for xor02-10+crc5).

Termination
-----------
The loop stops when no failing pixel is left, when a round resolved no new pixel ("no pixel
changes"; repeating the same illumination would only resample noise), when the next mask would
light nothing, or at ``max_rounds``.  A scene where nothing can be resolved therefore stops after
round 1 with every pixel invalid.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from edge.codes import Code

from .scheme import EdcScheme

DEFAULT_MIN_CONTRAST = 0.03  # shadow floor, fraction of full scale


@dataclass(frozen=True, eq=False)
class RoundResult:
    """Outcome of one round.

    Attributes:
        round: 1-based round index.
        frames: frames projected (and captured) this round, calibration included.
        calibration_frames: how many of them were calibration frames (2 in round 1, then 1).
        checked: camera pixels decoded this round (the still-failing ones).
        resolved: pixels that passed this round (now fixed).
        failing: pixels still failing after this round (shadow pixels excluded).
        lit_fraction: fraction of projector pixels lit by this round's pattern frames.
        error_map: (H, W) bool, True where a pixel was checked this round and failed.
    """

    round: int
    frames: int
    calibration_frames: int
    checked: int
    resolved: int
    failing: int
    lit_fraction: float
    error_map: np.ndarray


@dataclass(frozen=True, eq=False)
class AdaptiveResult:
    """Final state of an adaptive scan.

    Attributes:
        column: (H, W) int32 decoded codeword index (projector column // stripe), -1 = invalid.
        valid: (H, W) bool, column >= 0.
        round_of: (H, W) int8, round in which the pixel was resolved (0 = never).
        rounds: per-round results.
        stop_reason: "all resolved", "nothing to resolve" (no pixel over the shadow floor), "no change",
            "round limit" or "nothing to light".
    """

    column: np.ndarray
    valid: np.ndarray
    round_of: np.ndarray
    rounds: list[RoundResult]
    stop_reason: str
    scheme: str = ""
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def frames_per_round(self) -> list[int]:
        return [r.frames for r in self.rounds]

    @property
    def frames_total(self) -> int:
        return int(sum(r.frames for r in self.rounds))

    @property
    def n_rounds(self) -> int:
        return len(self.rounds)


def _as_scheme(scheme: Any) -> Any:
    if isinstance(scheme, (Code, str)):
        return EdcScheme(scheme)
    for attr in ("n_frames", "profiles", "decide", "codes", "name"):
        if not hasattr(scheme, attr):
            raise ValueError(f"expected a Code, a code name or a scheme with {attr!r}, got {type(scheme).__name__}")
    return scheme


class AdaptiveScan:
    """Adaptive re-projection loop with an explicit, runtime-drivable API.

    Usage::

        scan = AdaptiveScan(get_code("xor02-10+crc5"), projector_width=1024, height=480)
        frames = scan.start()                 # (n + 2, H, Wp) uint8: patterns, white, black
        while frames is not None:
            captured = camera.capture(frames)  # (len(frames), H, W)
            scan.update(captured)              # -> RoundResult
            frames = scan.next_frames()        # None when done
        result = scan.result()

    Args:
        scheme: a `Code` / code name (EDC: accept codewords) or a scheme object (see
            `edge.edc.scheme`), e.g. `edge.edc.gupta.EnsembleScheme`.
        projector_width: projector columns Wp.
        height: camera rows H (= projector rows: rectified pair).
        stripe: projector columns per codeword.
        max_rounds: round limit (>= 1).
        min_contrast: shadow floor on (white - black) as a fraction of ``full_scale``.
        full_scale: camera full-scale value (255 for 8 bits, 2**bits - 1 otherwise); default from the
            dtype of the first frames (uint8 -> 255, uint16 -> 65535, float -> 1).
        guard: keep lit the columns of passing pixels next to failing ones (see module docstring).
        disparity_band: optional (min_disparity, max_disparity) to light only candidate columns.
    """

    def __init__(self, scheme: Any, projector_width: int, height: int, *, stripe: int = 1, max_rounds: int = 3,
                 min_contrast: float = DEFAULT_MIN_CONTRAST, full_scale: float | None = None, guard: bool = True,
                 disparity_band: tuple[int, int] | None = None) -> None:
        self.scheme = _as_scheme(scheme)
        if int(projector_width) != projector_width or projector_width < 1:
            raise ValueError(f"projector_width must be a positive integer, got {projector_width!r}")
        if int(height) != height or height < 1:
            raise ValueError(f"height must be a positive integer, got {height!r}")
        if int(stripe) != stripe or stripe < 1:
            raise ValueError(f"stripe must be a positive integer, got {stripe!r}")
        if isinstance(max_rounds, bool) or int(max_rounds) != max_rounds or max_rounds < 1:
            raise ValueError(f"round limit max_rounds must be an integer >= 1, got {max_rounds!r}")
        if not 0.0 <= float(min_contrast) < 1.0:
            raise ValueError(f"min_contrast must be in [0, 1), got {min_contrast!r}")
        if full_scale is not None and not float(full_scale) > 0:
            raise ValueError(f"full_scale must be > 0, got {full_scale!r}")
        if disparity_band is not None and (len(disparity_band) != 2 or disparity_band[0] > disparity_band[1]):
            raise ValueError(f"disparity_band must be (min, max) with min <= max, got {disparity_band!r}")
        self.projector_width = int(projector_width)
        self.height = int(height)
        self.stripe = int(stripe)
        self.max_rounds = int(max_rounds)
        self.min_contrast = float(min_contrast)
        self.full_scale = None if full_scale is None else float(full_scale)
        self.guard = bool(guard)
        self.disparity_band = None if disparity_band is None else (int(disparity_band[0]), int(disparity_band[1]))
        self.n_columns = min(-(-self.projector_width // self.stripe), max(c.size for c in self.scheme.codes))
        self._profiles = self.scheme.profiles(self.projector_width, self.stripe)
        self._started = False

    # ------------------------------------------------------------------ state
    def start(self) -> np.ndarray:
        """Reset the scan; return round 1's projector frames (n + 2, H, Wp) uint8: patterns, white, black."""
        self._started = True
        self._round = 0
        self._rounds: list[RoundResult] = []
        self._stop: str | None = None
        self._camera_shape: tuple[int, int] | None = None
        self._column: np.ndarray | None = None
        self._lit = np.ones((self.height, self.projector_width), dtype=bool)
        self._expect = self.scheme.n_frames + 2
        return self._frames(self._lit, with_black=True)

    @property
    def done(self) -> bool:
        return self._started and self._stop is not None

    @property
    def expected_frames(self) -> int:
        """Number of frames the next `update` must receive."""
        self._require_started()
        return self._expect

    def _require_started(self) -> None:
        if not self._started:
            raise ValueError("adaptive scan not started: call start() first")

    def _frames(self, lit: np.ndarray, *, with_black: bool) -> np.ndarray:
        n = self.scheme.n_frames
        m = n + (2 if with_black else 1)
        out = np.zeros((m, self.height, self.projector_width), dtype=np.uint8)
        on = lit.astype(np.uint8) * np.uint8(255)
        for i in range(n):
            out[i] = (self._profiles[i] > 0.5).astype(np.uint8)[None, :] * on
        out[n] = on
        return out

    # ------------------------------------------------------------------ rounds
    def update(self, captured: np.ndarray, *, code: Code | str | None = None) -> RoundResult:
        """Decode the frames captured for the last frames handed out; fix the pixels that pass.

        captured: (m, H, W) camera frames in the order they were projected (patterns, white
        [, black in round 1]); uint8, uint16 or float.  code: optionally the code the frames were
        captured with; a different code than this scan's raises ValueError.
        """
        self._require_started()
        if self._stop is not None:
            raise ValueError(f"adaptive scan is finished ({self._stop}); call start() for a new scan")
        if code is not None:
            name = code if isinstance(code, str) else getattr(code, "name", repr(code))
            own = [c.name for c in self.scheme.codes]
            if name not in own and name != self.scheme.name:
                raise ValueError(f"frames of code {name!r} cannot continue a scan of {self.scheme.name!r}")
        f = np.asarray(captured)
        if f.ndim != 3:
            raise ValueError(f"captured frames must be (m, H, W), got shape {f.shape}")
        if f.shape[0] != self._expect:
            raise ValueError(
                f"round {self._round + 1} of {self.scheme.name!r} expects {self._expect} frames "
                f"({self.scheme.n_frames} patterns + {self._expect - self.scheme.n_frames} calibration), got {f.shape[0]}"
            )
        if f.shape[1] != self.height:
            raise ValueError(f"captured frames must have {self.height} rows (projector rows), got {f.shape[1]}")
        if self._camera_shape is not None and f.shape[1:] != self._camera_shape:
            raise ValueError(f"captured frames must be {self._camera_shape} like round 1, got {f.shape[1:]}")
        if not (np.issubdtype(f.dtype, np.integer) or np.issubdtype(f.dtype, np.floating)):
            raise ValueError(f"captured frames must be integer or float, got dtype {f.dtype}")
        n = self.scheme.n_frames
        self._round += 1
        first = self._round == 1
        if first:
            self._camera_shape = f.shape[1:]
            if self.full_scale is None:
                self.full_scale = float(np.iinfo(f.dtype).max) if np.issubdtype(f.dtype, np.integer) else 1.0
            h, w = self._camera_shape
            self._black = f[n + 1].astype(np.float32)
            self._column = np.full((h, w), -1, dtype=np.int32)
            self._round_of = np.zeros((h, w), dtype=np.int8)
            contrast = (f[n].astype(np.float32) - self._black) / np.float32(self.full_scale)
            self._pending = contrast > self.min_contrast  # shadow pixels never become pending
        white = f[n].astype(np.float32)
        ys, xs = np.nonzero(self._pending)
        pf = f[:n, ys, xs]
        pw = white[ys, xs]
        pb = self._black[ys, xs]
        column, passed = self.scheme.decide(pf, pw, pb)
        column = column.astype(np.int32)
        passed = passed & ((pw - pb) / np.float32(self.full_scale) > self.min_contrast)
        passed &= (column >= 0) & (column < self.n_columns)
        safe = np.clip(column, 0, self.n_columns - 1) * self.stripe
        passed &= self._lit[ys, np.minimum(safe, self.projector_width - 1)]
        h, w = self._camera_shape  # type: ignore[misc]
        error_map = np.zeros((h, w), dtype=bool)
        error_map[ys[~passed], xs[~passed]] = True
        ry, rx = ys[passed], xs[passed]
        self._column[ry, rx] = column[passed]  # type: ignore[index]
        self._round_of[ry, rx] = self._round
        self._pending[ry, rx] = False
        lit_fraction = float(self._lit.mean())
        result = RoundResult(
            round=self._round, frames=int(f.shape[0]), calibration_frames=int(f.shape[0] - n),
            checked=int(ys.size), resolved=int(ry.size), failing=int(self._pending.sum()),
            lit_fraction=lit_fraction, error_map=error_map,
        )
        self._rounds.append(result)
        # decide whether to go on, and with which mask
        if not self._pending.any():
            self._stop = "all resolved" if (self._column >= 0).any() else "nothing to resolve"
        elif result.resolved == 0:
            self._stop = "no change"
        elif self._round >= self.max_rounds:
            self._stop = "round limit"
        else:
            self._lit = self.next_mask()
            if not self._lit.any():
                self._stop = "nothing to light"
        self._expect = n + 1
        return result

    def next_mask(self) -> np.ndarray:
        """(H, Wp) bool projector pixels to light next round (rule: see the module docstring)."""
        self._require_started()
        if self._column is None:
            return np.ones((self.height, self.projector_width), dtype=bool)
        h, w = self._column.shape
        resolved = self._column >= 0
        claimed = np.zeros((h, self.n_columns), dtype=bool)
        ys, xs = np.nonzero(resolved)
        claimed[ys, self._column[ys, xs]] = True
        if self.guard:
            pend = self._pending
            for nb_resolved, nb_pixel in (
                (pend[:, 1:] & resolved[:, :-1], (0, -1)),   # resolved left neighbour of a failing pixel
                (pend[:, :-1] & resolved[:, 1:], (0, 1)),    # resolved right neighbour
            ):
                gy, gx = np.nonzero(nb_resolved)
                if nb_pixel[1] == -1:
                    gx = gx  # failing pixel at gx + 1, neighbour at gx
                else:
                    gx = gx + 1  # failing pixel at gx, neighbour at gx + 1
                claimed[gy, self._column[gy, gx]] = False
        stripes = np.repeat(~claimed, self.stripe, axis=1)
        lit = np.zeros((self.height, self.projector_width), dtype=bool)
        width = min(self.projector_width, stripes.shape[1])
        lit[:, :width] = stripes[:, :width]
        rows_pending = self._pending.any(axis=1)
        lit[~rows_pending] = False
        if self.disparity_band is not None:
            dmin, dmax = self.disparity_band
            py, px = np.nonzero(self._pending)
            lo = np.clip(px - dmax, 0, self.projector_width)
            hi = np.clip(px - dmin + 1, 0, self.projector_width)
            diff = np.zeros((self.height, self.projector_width + 1), dtype=np.int32)
            np.add.at(diff, (py, lo), 1)
            np.add.at(diff, (py, hi), -1)
            lit &= np.cumsum(diff, axis=1)[:, :-1] > 0
        return lit

    def next_frames(self) -> np.ndarray | None:
        """Projector frames (n + 1, H, Wp) uint8 of the next round (masked patterns, masked white), or None when done."""
        self._require_started()
        if not self._rounds:
            raise ValueError("no round decoded yet: project start()'s frames and call update() first")
        if self._stop is not None:
            return None
        return self._frames(self._lit, with_black=False)

    def result(self) -> AdaptiveResult:
        """The column map, valid mask and per-round statistics so far."""
        self._require_started()
        if self._column is None:
            raise ValueError("no round decoded yet: call update() first")
        return AdaptiveResult(
            column=self._column.copy(), valid=self._column >= 0, round_of=self._round_of.copy(),
            rounds=list(self._rounds), stop_reason=self._stop or "in progress", scheme=self.scheme.name,
        )


def run_adaptive(scene: Any, camera: Any, scheme: Any, *, rng: np.random.Generator | int | None = 0,
                 stripe: int = 1, max_rounds: int = 3, **options: Any) -> AdaptiveResult:
    """Drive an `AdaptiveScan` against the simulator end to end.

    Every frame (patterns and calibration, every round) is captured with `edge.sim.capture` at the
    per-frame exposure of a single pass of the scheme at fixed total exposure
    (``camera.frame_exposure(n_frames)``), with the global-illumination model of the scene, so
    switching columns off removes their indirect light.  ``options`` go to `AdaptiveScan`.
    """
    from edge.sim import capture

    gen = np.random.default_rng(rng) if not isinstance(rng, np.random.Generator) else rng
    scan = AdaptiveScan(scheme, int(scene.geometry.projector_width), scene.height, stripe=stripe,
                        max_rounds=max_rounds, full_scale=float(camera.levels), **options)
    exposure = camera.frame_exposure(scan.scheme.n_frames)
    frames = scan.start()
    while frames is not None:
        scan.update(capture(scene, frames, camera, rng=gen, exposure=exposure))
        frames = scan.next_frames()
    return scan.result()
