"""Adaptive structured light driven by an error map (paper section 4; Xu & Aliaga 2009; Gupta 2011).

Round 1 projects the full pattern set (plus a white and a black frame in the calibrated
binarisation mode, see below); every camera pixel is decoded and checked.  Pixels that pass are FIXED (never decoded
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
that code: free extra error detection), if its contrast is under the shadow / noise floor (see
"Binarisation"), or if no passing neighbour supports its column (see "Neighbour support").

Binarisation: self-calibrated (default) or calibrated
-----------------------------------------------------
``binarisation="self"`` (default): no white or black frame is captured in any round.  Each
camera pixel is binarised against the midpoint of its OWN extreme samples over the round's
pattern frames, ``bit_i = frame_i > (max + min) / 2``.  This needs every codeword to contain a 0
and a 1: the CRC-5 polynomial 0x15 has the factor x + 1, so every codeword of xor02-10+crc5 and
gray-10+crc5 has even weight, hence at most 14 ones of 15 (no all-one word); the only word
without a 1 is the all-zero codeword of column 0 (message 0).  Column 0 is therefore dark in every
pattern frame and can never be decoded in this mode -- it is never claimed, and the pixels that see
it are treated as shadow (`unmeasurable_columns` lists such columns for any scheme; for the Gupta
ensemble it is also column 0).  Because the threshold is recomputed from each round's own frames,
it follows the indirect light that masking removes, at no frame cost: a round costs exactly n
frames (15, 15, 15 = 45 for three rounds of a 15-frame code).
A pixel must also show a range ``max - min`` above the noise floor
``min_range_sigmas * sigma(max)`` with ``sigma(v)**2 = sigma_r**2 + sigma_s**2 * v + 1/(12 L**2)``
(the camera's read noise, shot-noise parameter and quantisation step, normalised; L = full
scale).  The default 6 sigma: the range of 15 samples of pure noise exceeds 6 sigma with
probability ~0.2% (5 sigma: 3%), while a real bit contrast of 6 sigma still binarises each bit with
error ~Q(3) = 0.13% (and the CRC catches the rest).  Pixels under the floor in round 1 are shadow
(never pending).  High-frequency codes help here: the indirect light a pixel outside the
projector's reach receives is nearly the same in every frame, so its range stays under the floor.

``binarisation="calibrated"``: round 1 adds a white (all on) and a black (all off) frame; the
threshold is ``(white + black) / 2`` and the shadow floor is ``white - black > min_contrast``
(fraction of full scale).  Switching columns off changes the indirect light every pixel receives,
so round 1's white no longer describes the "on" level: each round r >= 2 captures ONE new
calibration frame, the masked white (every lit projector pixel on); the black (ambient only) does
not depend on the mask and is reused.  Frames per round: n + 2, then n + 1 (17, 16, 16 = 49).

Neighbour support (false passes outside the projector's reach)
--------------------------------------------------------------
A camera pixel that the projector does not reach but that receives indirect light decodes a
near-random word, which is a codeword with probability ~2**-(n-k) (1/32 for a CRC-5).  A passing
pixel must therefore also be *supported*: some 8-neighbour has passed (in an earlier round or this
one) with a column within ``neighbour_tolerance`` codewords of its own.  On a continuous surface
neighbouring pixels see neighbouring projector columns; a chance codeword agrees with a neighbour
with probability ~(2 tol + 1) / 2**k per passing neighbour.  An unsupported pixel fails this round
(it is re-measured if rounds are left).  ``neighbour_tolerance=None`` switches the check off.

Never worse than a single pass
------------------------------
Only OPEN pixels are decoded in a round (the sparse pixel list of `edge.edc._kernels`); a
verified column is never replaced and never invalidated by a later round.  An open pixel's column
is replaced only by a decode that passes the check AND the neighbour support.  What a pixel
reports while open (``keep_guess``, default on): its GUESS -- the nearest codeword of its word
(the ensemble: the majority column), i.e. what an unchecked single pass reports; round 1's, or,
for a pixel not reported yet (``update_guesses``, default on), the latest round's -- where a
chain of neighbours with columns within the support tolerance links it to a verified pixel (region
growing from the verified pixels, `edge.edc._kernels.grow_guesses`); otherwise nothing.  A pixel
reported once stays reported (its column can only be replaced by a verified decode).
A correct pixel whose word failed the check (a bit flipped in a CRC bit, e.g. gray-10+crc5 under
inter-reflection) therefore stays correct, and a wrong guess is kept only when it lies within the
tolerance of its neighbours' columns along such a chain.  Verified pixels only accumulate, so the
reported set only grows from round to round.

Termination
-----------
The loop stops when no failing pixel is left, when a round resolved no new pixel ("no pixel
changes"; repeating the same illumination would only resample noise), when the next mask would
light nothing, or at ``max_rounds``.  Without masking (the re-project-everything baseline) a round
that resolves nothing does not stop the loop: only the round limit does.  A scene where nothing can be resolved therefore stops after
round 1 with every pixel invalid.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from edge.capture import bit_depth_of, full_scale
from edge.codes import Code
from edge.decode.inputs import native

from . import _kernels
from .scheme import EdcScheme, unmeasurable_columns

DEFAULT_MIN_CONTRAST = 0.03  # calibrated mode: shadow floor on white - black, fraction of full scale
DEFAULT_MIN_RANGE_SIGMAS = 6.0  # self-calibrated mode: floor on max - min, in noise sigmas
DEFAULT_NOISE = (0.002, 0.015)  # (sigma_r, sigma_s) normalised: the `edge.sim.CameraModel` defaults
DEFAULT_NEIGHBOUR_TOLERANCE = 3  # codewords
BINARISATIONS = ("self", "calibrated")


@dataclass(frozen=True, eq=False)
class RoundResult:
    """Outcome of one round.

    Attributes:
        round: 1-based round index.
        frames: frames projected (and captured) this round, calibration included.
        calibration_frames: how many of them were calibration frames (self-calibrated: 0;
            calibrated: 2 in round 1, then 1).
        checked: camera pixels decoded this round (the still-failing ones).
        resolved: pixels that passed this round (now fixed).
        failing: pixels still failing after this round (shadow pixels excluded).
        unsupported: pixels whose word was a lit codeword but that no passing neighbour supported.
        lit_fraction: fraction of projector pixels lit by this round's pattern frames.
        error_map: (H, W) bool, True where a pixel was checked this round and failed.
        valid: pixels reported valid after this round (verified + supported guesses).
        decode_s: seconds `update` spent on this round (decode of the open pixels, mask).
    """

    round: int
    frames: int
    calibration_frames: int
    checked: int
    resolved: int
    failing: int
    unsupported: int
    lit_fraction: float
    error_map: np.ndarray
    valid: int = 0
    decode_s: float = 0.0


@dataclass(frozen=True, eq=False)
class AdaptiveResult:
    """Final state of an adaptive scan.

    Attributes:
        column: (H, W) int32 decoded codeword index (projector column // stripe), -1 = invalid.
        valid: (H, W) bool, column >= 0.
        round_of: (H, W) int8, round in which the pixel was verified (0 = never).
        verified: (H, W) bool, the column passed the check and neighbour support in some round
            (the other valid pixels kept their round-1 guess because verified neighbours support it).
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
    verified: np.ndarray | None = None

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


def supported(column: np.ndarray, candidate: np.ndarray, tolerance: int) -> np.ndarray:
    """(H, W) bool: candidate pixels whose column a passing neighbour supports.

    column: (H, W) int, the columns of every passing pixel (fixed earlier or candidate now), -1
    elsewhere; candidate: (H, W) bool, the pixels to test (their own entry in ``column`` is set).

    Supported = some neighbour at dx = +-1 (6 pixels) has a column within ``tolerance``, or, when
    none of those 6 has a column at all, the pixel above or below has one within ``tolerance``.
    Vertical agreement alone is weak evidence: a systematic binarisation error along a vertical
    edge (e.g. the border of a scattering region) repeats the same wrong column down the edge;
    across the epipolar direction a surface's column changes smoothly.  It still counts for a
    pixel with no decoded horizontal neighbour (a one-pixel-wide lit strip next to a shadow).
    """
    h, w = column.shape
    pad = np.full((h + 2, w + 2), -1, dtype=np.int64)
    pad[1:-1, 1:-1] = column
    own = column.astype(np.int64)
    near_h = np.zeros((h, w), dtype=bool)
    any_h = np.zeros((h, w), dtype=bool)
    near_v = np.zeros((h, w), dtype=bool)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            if dy == 0 and dx == 0:
                continue
            nb = pad[1 + dy:1 + dy + h, 1 + dx:1 + dx + w]
            near = (nb >= 0) & (np.abs(nb - own) <= tolerance)
            if dx == 0:
                near_v |= near
            else:
                near_h |= near
                any_h |= nb >= 0
    return candidate & (near_h | (~any_h & near_v))


class AdaptiveScan:
    """Adaptive re-projection loop with an explicit, runtime-drivable API.

    Usage::

        scan = AdaptiveScan(get_code("xor02-10+crc5"), projector_width=1024, height=480)
        frames = scan.start()                 # (n, H, Wp) uint8 patterns (+ white, black if calibrated)
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
        binarisation: "self" (per-pixel midpoint of its own min and max sample, no calibration
            frames) or "calibrated" (white and black frames); see the module docstring.
        min_contrast: calibrated mode: shadow floor on (white - black) as a fraction of ``full_scale``.
        min_range_sigmas: self-calibrated mode: floor on (max - min) in noise sigmas.
        noise: self-calibrated mode: camera (sigma_r, sigma_s), normalised units (variance
            ``sigma_r**2 + sigma_s**2 * v`` at normalised level v).
        full_scale: camera full-scale value (255 for 8 bits, 2**bits - 1 otherwise); default from the
            first round's frames by `decode`'s rule (uint8 -> 255, float -> 1, uint16 -> 2**b - 1 for
            the smallest b of 8, 10, 12, 14, 16 that holds their largest value, so 12-bit data in
            uint16 is not read 16x darker).
        guard: keep lit the columns of passing pixels next to failing ones (see module docstring).
        disparity_band: optional (min_disparity, max_disparity) to light only candidate columns.
        neighbour_tolerance: a passing pixel needs an 8-neighbour that passed with a column within
            this many codewords (None: no neighbour check).
        keep_guess: an open pixel is reported with its guess (nearest codeword; ensemble majority)
            where a chain of neighbours links it to a verified pixel (see "Never worse").
        update_guesses: an open pixel that is not reported yet takes each later round's guess
            (measured with less indirect light) instead of keeping its round-1 guess.
        masking: False = the plain "re-project everything again" baseline: every round projects the
            full pattern set (nothing is switched off) until the round limit.
    """

    def __init__(self, scheme: Any, projector_width: int, height: int, *, stripe: int = 1, max_rounds: int = 3,
                 binarisation: str = "self", min_contrast: float = DEFAULT_MIN_CONTRAST,
                 min_range_sigmas: float = DEFAULT_MIN_RANGE_SIGMAS, noise: tuple[float, float] = DEFAULT_NOISE,
                 full_scale: float | None = None, guard: bool = True,
                 disparity_band: tuple[int, int] | None = None,
                 neighbour_tolerance: int | None = DEFAULT_NEIGHBOUR_TOLERANCE, keep_guess: bool = True,
                 masking: bool = True, update_guesses: bool = True) -> None:
        self.scheme = _as_scheme(scheme)
        if int(projector_width) != projector_width or projector_width < 1:
            raise ValueError(f"projector_width must be a positive integer, got {projector_width!r}")
        if int(height) != height or height < 1:
            raise ValueError(f"height must be a positive integer, got {height!r}")
        if int(stripe) != stripe or stripe < 1:
            raise ValueError(f"stripe must be a positive integer, got {stripe!r}")
        if isinstance(max_rounds, bool) or int(max_rounds) != max_rounds or max_rounds < 1:
            raise ValueError(f"round limit max_rounds must be an integer >= 1, got {max_rounds!r}")
        if binarisation not in BINARISATIONS:
            raise ValueError(f"binarisation must be one of {BINARISATIONS}, got {binarisation!r}")
        if not 0.0 <= float(min_contrast) < 1.0:
            raise ValueError(f"min_contrast must be in [0, 1), got {min_contrast!r}")
        if not float(min_range_sigmas) >= 0.0:
            raise ValueError(f"min_range_sigmas must be >= 0, got {min_range_sigmas!r}")
        if len(noise) != 2 or not all(float(v) >= 0.0 for v in noise):
            raise ValueError(f"noise must be (sigma_r, sigma_s) with both >= 0, got {noise!r}")
        if full_scale is not None and not float(full_scale) > 0:
            raise ValueError(f"full_scale must be > 0, got {full_scale!r}")
        if disparity_band is not None and (len(disparity_band) != 2 or disparity_band[0] > disparity_band[1]):
            raise ValueError(f"disparity_band must be (min, max) with min <= max, got {disparity_band!r}")
        if neighbour_tolerance is not None and (int(neighbour_tolerance) != neighbour_tolerance
                                                or neighbour_tolerance < 0):
            raise ValueError(f"neighbour_tolerance must be None or an integer >= 0, got {neighbour_tolerance!r}")
        self.projector_width = int(projector_width)
        self.height = int(height)
        self.stripe = int(stripe)
        self.max_rounds = int(max_rounds)
        self.binarisation = binarisation
        self.min_contrast = float(min_contrast)
        self.min_range_sigmas = float(min_range_sigmas)
        self.noise = (float(noise[0]), float(noise[1]))
        self.full_scale = None if full_scale is None else float(full_scale)
        self.guard = bool(guard)
        self.disparity_band = None if disparity_band is None else (int(disparity_band[0]), int(disparity_band[1]))
        self.neighbour_tolerance = None if neighbour_tolerance is None else int(neighbour_tolerance)
        self.keep_guess = bool(keep_guess)
        self.update_guesses = bool(update_guesses)
        self.fast_round1 = True  # round 1 of an EdcScheme in one kernel pass (False: the generic path)
        self.masking = bool(masking)
        self.n_columns = min(-(-self.projector_width // self.stripe), max(c.size for c in self.scheme.codes))
        self._profiles = self.scheme.profiles(self.projector_width, self.stripe)
        # columns a self-calibrated round cannot decode (constant word over the round's frames)
        self.unmeasurable = (unmeasurable_columns(self.scheme)[: self.n_columns] if binarisation == "self"
                             else np.zeros(self.n_columns, dtype=bool))
        self._started = False

    @property
    def self_calibrated(self) -> bool:
        return self.binarisation == "self"

    # ------------------------------------------------------------------ state
    def start(self) -> np.ndarray:
        """Reset the scan; return round 1's projector frames (m, H, Wp) uint8.

        Self-calibrated: the n pattern frames.  Calibrated: n patterns, white, black.
        """
        self._started = True
        self._round = 0
        self._rounds: list[RoundResult] = []
        self._stop: str | None = None
        self._camera_shape: tuple[int, int] | None = None
        self._column: np.ndarray | None = None
        self._lit = np.ones((self.height, self.projector_width), dtype=bool)
        self._expect = self.scheme.n_frames + (0 if self.self_calibrated else 2)
        return self._frames(self._lit, first=True)

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

    def _frames(self, lit: np.ndarray, *, first: bool) -> np.ndarray:
        n = self.scheme.n_frames
        m = n if self.self_calibrated else n + (2 if first else 1)
        out = np.zeros((m, self.height, self.projector_width), dtype=np.uint8)
        rows = np.nonzero(lit.any(axis=1))[0]  # dark rows stay zero
        on = lit[rows].astype(np.uint8) * np.uint8(255)
        bits = (self._profiles > 0.5).astype(np.uint8)
        for i in range(n):
            out[i, rows] = bits[i][None, :] * on
        if not self.self_calibrated:
            out[n, rows] = on  # white (masked in rounds >= 2); the black frame stays all zero
        return out

    def noise_floor(self, level: np.ndarray) -> np.ndarray:
        """Self-calibrated floor on max - min (normalised) at normalised level ``level``."""
        sr, ss = self.noise
        q = 1.0 / (12.0 * float(self.full_scale) ** 2) if self.full_scale and self.full_scale > 1.0 else 0.0
        var = sr * sr + ss * ss * np.clip(level, 0.0, None) + q
        return np.float32(self.min_range_sigmas) * np.sqrt(var).astype(np.float32)

    # ------------------------------------------------------------------ rounds
    def update(self, captured: np.ndarray, *, code: Code | str | None = None,
               guess: np.ndarray | None = None) -> RoundResult:
        """Decode the frames captured for the last frames handed out; fix the pixels that pass.

        guess: round 1 only, optional (H, W) int columns (-1 = none) to keep for open pixels instead
        of the scheme's own guess (the runtime passes its soft decoder's columns).

        captured: (m, H, W) camera frames in the order they were projected (patterns, then white
        [, black in round 1] when calibrated); uint8, uint16 or float.  code: optionally the code
        the frames were captured with; a different code than this scan's raises ValueError.
        """
        self._require_started()
        given = guess
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
        n = self.scheme.n_frames
        if f.shape[0] != self._expect:
            raise ValueError(
                f"round {self._round + 1} of {self.scheme.name!r} expects {self._expect} frames "
                f"({n} patterns + {self._expect - n} calibration), got {f.shape[0]}"
            )
        if f.shape[1] != self.height:
            raise ValueError(f"captured frames must have {self.height} rows (projector rows), got {f.shape[1]}")
        if self._camera_shape is not None and f.shape[1:] != self._camera_shape:
            raise ValueError(f"captured frames must be {self._camera_shape} like round 1, got {f.shape[1:]}")
        if not (np.issubdtype(f.dtype, np.integer) or np.issubdtype(f.dtype, np.floating)):
            raise ValueError(f"captured frames must be integer or float, got dtype {f.dtype}")
        self._round += 1
        first = self._round == 1
        t0 = time.perf_counter()
        if first:
            self._camera_shape = f.shape[1:]
            if self.full_scale is None:
                # the one full-scale rule (edge.capture) at the bit depth decode() detects
                self.full_scale = full_scale(f.dtype, bit_depth_of([("frames", native(f))], None))
            h, w = self._camera_shape
            self._column = np.full((h, w), -1, dtype=np.int32)
            self._guess = np.full((h, w), -1, dtype=np.int32)
            self._out_prev = None
            self._round_of = np.zeros((h, w), dtype=np.int8)
        f = np.ascontiguousarray(f)
        if first and self.fast_round1 and isinstance(self.scheme, EdcScheme):
            return self._round1_edc(f, given, t0)
        if first:
            if self.self_calibrated:
                hi_img, lo_img = _kernels.extremes_full(f, n)
            else:
                self._black = np.ascontiguousarray(f[n + 1])
                hi_img, lo_img = f[n], self._black
            self._pending = self._contrast_ok(hi_img, lo_img)  # shadow pixels never become pending
            ys, xs = np.nonzero(self._pending)
            if not hasattr(self.scheme, "decide_full"):
                hi = hi_img[ys, xs].astype(np.float32)
                lo = lo_img[ys, xs].astype(np.float32)
        else:
            ys, xs = np.nonzero(self._pending)
            if self.self_calibrated:
                hi, lo = _kernels.gather_extremes(f, ys, xs, n)
            else:
                hi = _kernels.gather_pixels(f[n], ys, xs)
                lo = _kernels.gather_pixels(self._black, ys, xs)
        if first and hasattr(self.scheme, "decide_full"):
            column, passed, own_guess = self.scheme.decide_full(f, hi_img, lo_img, ys, xs)
        elif hasattr(self.scheme, "decide_at"):
            column, passed, own_guess = self.scheme.decide_at(f, ys, xs, hi, lo)
        else:
            column, passed = self.scheme.decide(f[:n, ys, xs], hi, lo)
            own_guess = column
        column = np.asarray(column, dtype=np.int32)
        # round 1: every pending pixel is over the floor (that is what made it pending) and all is lit
        measurable = np.ones(ys.size, dtype=bool) if first else self._contrast_ok(hi, lo)
        passed = passed & measurable & (column >= 0) & (column < self.n_columns)
        safe = np.clip(column, 0, self.n_columns - 1)
        passed &= ~self.unmeasurable[safe]
        if not first:
            passed &= self._lit[ys, np.minimum(safe * self.stripe, self.projector_width - 1)]
        if first:  # the single-pass guess (nearest codeword / majority) of every measurable pixel
            if given is not None:
                g = np.asarray(given)
                if g.shape != self._camera_shape:
                    raise ValueError(f"guess must be a {self._camera_shape} column map like the frames, got {g.shape}")
                g = g[ys, xs].astype(np.int32)
            else:
                g = np.asarray(own_guess, dtype=np.int32)
            g_ok = measurable & (g >= 0) & (g < self.n_columns)
            g_ok &= ~self.unmeasurable[np.clip(g, 0, self.n_columns - 1)]
            self._guess[ys, xs] = np.where(g_ok, g, -1)
        elif self.update_guesses and self._out_prev is not None:
            # an open pixel not reported yet takes this round's guess (measured with less indirect
            # light); a reported pixel keeps the guess it is reported with
            g = np.asarray(own_guess, dtype=np.int32)
            free = (self._out_prev[ys, xs] < 0) & measurable & (g >= 0) & (g < self.n_columns)
            free &= ~self.unmeasurable[np.clip(g, 0, self.n_columns - 1)]
            free &= self._lit[ys, np.minimum(np.clip(g, 0, self.n_columns - 1) * self.stripe, self.projector_width - 1)]
            self._guess[ys[free], xs[free]] = g[free]
        h, w = self._camera_shape  # type: ignore[misc]
        unsupported = 0
        if self.neighbour_tolerance is not None and passed.any():
            idx = np.nonzero(passed)[0]
            py, px, pc = ys[idx], xs[idx], column[idx]
            ref = self._column.copy()  # type: ignore[union-attr]
            ref[py, px] = pc
            ok = _kernels.support_at(py, px, pc, ref, self.neighbour_tolerance)
            unsupported = int((~ok).sum())
            passed[idx[~ok]] = False
        error_map = np.zeros((h, w), dtype=bool)
        error_map[ys[~passed], xs[~passed]] = True
        ry, rx = ys[passed], xs[passed]
        # only open pixels are decoded: a verified column is never replaced or invalidated
        self._column[ry, rx] = column[passed]  # type: ignore[index]
        self._round_of[ry, rx] = self._round
        self._pending[ry, rx] = False
        return self._finish_round(f, checked=int(ys.size), resolved=int(ry.size), unsupported=unsupported,
                                  error_map=error_map, t0=t0)

    def _round1_edc(self, f: np.ndarray, given: np.ndarray | None, t0: float) -> RoundResult:
        """Round 1 of an `EdcScheme` in one pass over the frame (`edge.edc._kernels.round1_words`);
        the same decisions as the generic path (tests compare them)."""
        from .lookup import membership_table, packed_codewords

        n = self.scheme.n_frames
        if given is not None:
            given = np.asarray(given)
            if given.shape != self._camera_shape:
                raise ValueError(f"guess must be a {self._camera_shape} column map like the frames, got {given.shape}")
            given = np.ascontiguousarray(given, dtype=np.int32)
        if not self.self_calibrated:
            self._black = np.ascontiguousarray(f[n + 1])
        white = f[n] if not self.self_calibrated else f[0]
        black = self._black if not self.self_calibrated else f[0]
        sr, ss = self.noise
        fs = float(self.full_scale)  # type: ignore[arg-type]
        q = 1.0 / (12.0 * fs ** 2) if fs > 1.0 else 0.0
        cand, pend, guess = _kernels.round1_words(
            f, n, np.ascontiguousarray(white), black, self.self_calibrated, fs, self.min_contrast,
            self.min_range_sigmas, sr * sr, ss * ss, q, membership_table(self.scheme.code),
            packed_codewords(self.scheme.code), given if given is not None else np.zeros((1, 1), np.int32),
            given is not None, self.n_columns, self.unmeasurable)
        self._guess = guess
        passed = cand >= 0
        unsupported = 0
        if self.neighbour_tolerance is not None:
            ok = _kernels.support_full(cand, self.neighbour_tolerance)
            unsupported = int(np.count_nonzero(passed)) - int(np.count_nonzero(ok))
            passed = ok
        self._column = np.where(passed, cand, np.int32(-1)).astype(np.int32)
        self._round_of = passed.astype(np.int8)
        checked = int(np.count_nonzero(pend))
        self._pending = pend & ~passed
        return self._finish_round(f, checked=checked, resolved=int(np.count_nonzero(passed)),
                                  unsupported=unsupported, error_map=self._pending.copy(), t0=t0)

    def _finish_round(self, f: np.ndarray, *, checked: int, resolved: int, unsupported: int,
                      error_map: np.ndarray, t0: float) -> RoundResult:
        n = self.scheme.n_frames
        lit_fraction = float(self._lit.mean())
        if not self._pending.any():
            self._stop = "all resolved" if (self._column >= 0).any() else "nothing to resolve"  # type: ignore[operator]
        elif resolved == 0 and self.masking:
            self._stop = "no change"
        elif self._round >= self.max_rounds:
            self._stop = "round limit"
        else:
            self._lit = self.next_mask() if self.masking else np.ones_like(self._lit)
            if not self._lit.any():
                self._stop = "nothing to light"
        output = self._out_cache = self._output()
        result = RoundResult(
            round=self._round, frames=int(f.shape[0]), calibration_frames=int(f.shape[0] - n),
            checked=checked, resolved=resolved, failing=int(self._pending.sum()),
            unsupported=unsupported, lit_fraction=lit_fraction, error_map=error_map,
            valid=int((output >= 0).sum()), decode_s=time.perf_counter() - t0,
        )
        self._rounds.append(result)
        self._expect = n + (0 if self.self_calibrated else 1)
        return result

    def _output(self) -> np.ndarray:
        """(H, W) int32 reported columns: verified pixels, plus (``keep_guess``) the open pixels whose
        round-1 guess joins a reported pixel through a chain of neighbours with columns within the
        support tolerance (`edge.edc._kernels.grow_guesses`).  Growing starts from what the previous
        round reported (with verified columns in place), so a reported pixel stays reported: a later
        round can only replace its column by a verified one, never drop it."""
        if not self.keep_guess:
            return self._column.copy()  # type: ignore[union-attr]
        tol = self.neighbour_tolerance if self.neighbour_tolerance is not None else DEFAULT_NEIGHBOUR_TOLERANCE
        base = self._column.copy() if self._out_prev is None else self._out_prev.copy()  # type: ignore[union-attr]
        verified = self._column >= 0  # type: ignore[operator]
        base[verified] = self._column[verified]  # type: ignore[index]
        gy, gx = np.nonzero(self._pending & (self._guess >= 0) & (base < 0))
        out = _kernels.grow_guesses(base, self._guess, gy, gx, tol)
        self._out_prev = out
        return out

    def _contrast_ok(self, hi: np.ndarray, lo: np.ndarray) -> np.ndarray:
        """Bool: the pixel's contrast (max - min, or white - black) is over the mode's floor."""
        fs = np.float32(self.full_scale)
        hi_n = np.asarray(hi, dtype=np.float32) / fs
        contrast = hi_n - np.asarray(lo, dtype=np.float32) / fs
        if self.self_calibrated:
            return contrast > self.noise_floor(hi_n)
        return contrast > self.min_contrast

    @property
    def guesses(self) -> np.ndarray:
        """(H, W) int32 round-1 guess of every pixel over the floor (nearest codeword / majority), -1
        elsewhere: what an unchecked single pass with this scan's binarisation reports."""
        if self._column is None:
            raise ValueError("no round decoded yet: call update() first")
        return self._guess.copy()

    def next_mask(self) -> np.ndarray:
        """(H, Wp) bool projector pixels to light next round (rule: see the module docstring).

        Only the rows that still hold an open pixel are computed (every other row is dark).
        """
        self._require_started()
        if self._column is None:
            return np.ones((self.height, self.projector_width), dtype=bool)
        lit = np.zeros((self.height, self.projector_width), dtype=bool)
        rows = np.nonzero(self._pending.any(axis=1))[0]
        if rows.size == 0:
            return lit
        col = self._column[rows]
        pend = self._pending[rows]
        resolved = col >= 0
        claimed = np.zeros((rows.size, self.n_columns), dtype=bool)
        ys, xs = np.nonzero(resolved)
        claimed[ys, col[ys, xs]] = True
        if self.guard:
            # the resolved left / right neighbour of an open pixel keeps its column lit
            gy, gx = np.nonzero(pend[:, 1:] & resolved[:, :-1])
            claimed[gy, col[gy, gx]] = False
            gy, gx = np.nonzero(pend[:, :-1] & resolved[:, 1:])
            claimed[gy, col[gy, gx + 1]] = False
        stripes = np.repeat(~claimed, self.stripe, axis=1)
        width = min(self.projector_width, stripes.shape[1])
        sub = np.zeros((rows.size, self.projector_width), dtype=bool)
        sub[:, :width] = stripes[:, :width]
        if self.disparity_band is not None:
            dmin, dmax = self.disparity_band
            py, px = np.nonzero(pend)
            lo = np.clip(px - dmax, 0, self.projector_width)
            hi = np.clip(px - dmin + 1, 0, self.projector_width)
            size = rows.size * (self.projector_width + 1)
            diff = (np.bincount(py * (self.projector_width + 1) + lo, minlength=size)
                    - np.bincount(py * (self.projector_width + 1) + hi, minlength=size))
            sub &= np.cumsum(diff.reshape(rows.size, -1), axis=1)[:, :-1] > 0
        lit[rows] = sub
        return lit

    def next_frames(self) -> np.ndarray | None:
        """Projector frames of the next round (masked patterns [+ masked white if calibrated]), or None when done."""
        self._require_started()
        if not self._rounds:
            raise ValueError("no round decoded yet: project start()'s frames and call update() first")
        if self._stop is not None:
            return None
        return self._frames(self._lit, first=False)

    def run(self, capture: Callable[[np.ndarray], np.ndarray], *, guess: np.ndarray | None = None) -> AdaptiveResult:
        """The whole loop, the one driver of a scan: `start`, then ``update(capture(frames))`` for
        every round's projector frames until `next_frames` says done; returns `result`.

        capture: (m, H, Wp) uint8 projector frames -> (m, H, W) captured camera frames (round 1
        may also be frames already captured, e.g. the service's stack).  guess: round 1's
        ``guess`` (see `update`).
        """
        frames = self.start()
        first = True
        while frames is not None:
            self.update(capture(frames), guess=guess if first else None)
            first = False
            frames = self.next_frames()
        return self.result()

    def result(self) -> AdaptiveResult:
        """The column map, valid mask and per-round statistics so far."""
        self._require_started()
        if self._column is None:
            raise ValueError("no round decoded yet: call update() first")
        column = self._out_cache.copy()  # the state only changes in update()
        return AdaptiveResult(
            column=column, valid=column >= 0, round_of=self._round_of.copy(),
            rounds=list(self._rounds), stop_reason=self._stop or "in progress", scheme=self.scheme.name,
            verified=self._column >= 0,
        )


def run_adaptive(scene: Any, camera: Any, scheme: Any, *, rng: np.random.Generator | int | None = 0,
                 stripe: int = 1, max_rounds: int = 3, **options: Any) -> AdaptiveResult:
    """Drive an `AdaptiveScan` against the simulator end to end.

    Every frame (patterns and calibration, every round) is captured with `edge.sim.capture` at the
    per-frame exposure of a single pass of the scheme at fixed total exposure
    (``camera.frame_exposure(n_frames)``), with the global-illumination model of the scene, so
    switching columns off removes their indirect light.  ``options`` go to `AdaptiveScan`; the
    self-calibrated noise floor uses the camera's ``(sigma_r, sigma_s)`` unless ``noise`` is given.
    """
    from edge.sim import capture

    gen = np.random.default_rng(rng) if not isinstance(rng, np.random.Generator) else rng
    options.setdefault("noise", (float(camera.sigma_r), float(camera.sigma_s)))
    scan = AdaptiveScan(scheme, int(scene.geometry.projector_width), scene.height, stripe=stripe,
                        max_rounds=max_rounds, full_scale=float(camera.levels), **options)
    exposure = camera.frame_exposure(scan.scheme.n_frames)
    return scan.run(lambda frames: capture(scene, frames, camera, rng=gen, exposure=exposure))
