"""Stack -> depth: the per-stack processing chain of the service, as one deterministic function.

``DepthPipeline(profile).process(stack)`` runs, in order:

1. matched filter (when ``profile.code.source`` is set): the L slots of every projector frame
   are de-spread into one image (`edge.source.despread`);
2. split into the n code frames, the white and the black calibration frame;
3. decoder (`edge.decode.decode` with the profile's `DecodeSettings`, `from_profile`, and
   disparity band) and its valid mask: by default (``decoder.validity = "auto"``, a soft method)
   the error-probability rule, valid where the estimated P(wrong column) < ``decoder.max_error``,
   published as the result's ``error`` image; else the contrast / confidence thresholds
   (``decoder.min_contrast`` on (white - black), ``decoder.min_confidence``).  With
   ``decoder.backend`` "cuda" under the "confidence" rule the frames were uploaded while they
   were captured (the capture hook `on_frame`, see `DepthPipeline.__init__`) and the decode
   reads that staged set; a stack that was not staged is uploaded whole; either way only
   column, confidence and the valid mask come back to the host, with the same values (under
   the "error" rule `decode` runs the whole error rule on the device, without frame staging
   here, and brings back the whole `Decoded`);
4. EDC (when ``edc.rounds`` > 0): `edge.decode.check` error map and the adaptive loop
   (`edge.edc`), which asks ``masked_capture`` for the next masked frames;
5. column -> disparity -> depth (`edge.runtime.depth.column_to_depth_mm`, profile geometry).

It is the ``columns`` kind of `edge.device.PIPELINES` (built by `edge.runtime.pipelines.make_pipeline`).

Nothing here depends on time, threads or randomness, so `edge replay` calls the same `process`
on recorded frames and gets the same depth bit for bit.  Call it from ONE thread (numba parallel
kernels).
"""

from __future__ import annotations

import time

import numpy as np

from edge.device import DeviceModel

from ..decode.inputs import NoPatternContrast
from ..sensors.base import Frame
from .assembly import Stack
from .depth import column_to_depth_mm, confidence_to_u8, error_image
from .result import DepthResult, MaskedCaptureFn

class DepthPipeline:
    """Processing chain for one profile (see module docstring).  Build once, call `process` per stack."""

    def __init__(self, profile) -> None:
        from edge.codes import get_code

        if profile.projector.kind != "columns":
            raise ValueError(
                f"DepthPipeline decodes 'columns' projectors (coded patterns); profile {profile.name!r} "
                f"has projector.kind = {profile.projector.kind!r} (use make_pipeline)")
        self.profile = profile
        self.device = DeviceModel.from_profile(profile)
        self.code = get_code(profile.code.name)
        self.n, self.source_length = self.device.n_code_frames, self.device.source_length
        self.schedule = self.device.schedule
        self.geometry = profile.geometry
        self.stripe = int(profile.projector.stripe)
        self.columns = min(self.code.size, -(-int(profile.projector.width) // self.stripe))
        self.full_scale = self.device.full_scale
        self.source_bits = (np.array([c == "1" for c in profile.code.source], dtype=bool)
                            if profile.code.source else None)
        if self.source_bits is not None and self.source_bits.all():
            self.source_bits = None  # an all-ones code ("1", "11"...) is no spreading at all
        #: source codes of the other devices in the room (set by ``edge run --room``): when given, the
        #: matched filter is the joint decorrelating one (`edge.source.joint`) instead of `despread`
        self.foreign_sources: tuple[str, ...] = ()
        #: the decoder settings of the profile and the decode function of its backend, chosen once
        #: here (a live config change builds a new pipeline): `decode`, or for the CUDA backend
        #: `decode_staged` (pinned buffers + a stream, same results) downloading only the fields
        #: the depth uses (column, confidence, valid: `HOST_OUTPUTS`; candidates / distances stay
        #: on the device and are None in the `Decoded` this pipeline's `decode` returns)
        from edge.decode import decode
        from edge.decode.backends import get as get_backend
        from edge.decode.settings import from_profile

        self.settings = from_profile(profile)
        self._decode = decode
        #: the capture hook ``on_frame(index, frame)`` (`StackAssembler.on_frame`, set by the
        #: service): None for the CPU backend (nothing is imported or called per frame); for the
        #: CUDA backend, when every stack image is one camera frame (no source code), a
        #: `FrameStager` that uploads each frame as it is captured, so `process` decodes a
        #: complete stack from its staged set (the decode waits only for that set's stream) and
        #: uploads the stack whole only when it was not staged (a dropped frame, a busy /
        #: reclaimed set, a stack not from the service's assembler).  The service allocates the
        #: sets before capture (`prepare_capture`) and a new pipeline keeps the previous one's
        #: staged frames (`continue_from`).
        self.on_frame = None
        self.stager = None
        #: the validity rule of the service's stacks (code frames, white, black: no inverse frames)
        self.rule = self.settings.rule(False)
        # frames are staged under either rule: the device runs the error rule's stages too
        # (`edge.decode.backends.cuda.pipeline.error_device`)
        if (self.settings.backend != "cpu"
                and get_backend(self.settings.backend).__name__.endswith(".cuda")):
            import functools

            from edge.decode.backends.cuda.pipeline import HOST_OUTPUTS
            from edge.decode.backends.cuda.staging import FrameStager, decode_staged

            self._outputs = HOST_OUTPUTS
            self._decode = functools.partial(decode_staged, outputs=HOST_OUTPUTS)
            if self.source_bits is None and self.schedule.size == self.n + 2:
                self.stager = FrameStager(self.n + 2)
                self.on_frame = self.stager.put

    def continue_from(self, previous) -> None:
        """Take over `previous` pipeline's staged frames (the service swaps pipelines between
        stacks, e.g. a live config change): when both stage frames of the same stack layout,
        this pipeline uses the previous `FrameStager` (raw frames: independent of the decoder
        settings), so a stack staged before the change still decodes from its staged set and no
        pinned memory is allocated again."""
        old = getattr(previous, "stager", None)
        if self.stager is not None and old is not None and old.slots == self.stager.slots:
            self.stager = old
            self.on_frame = old.put

    def prepare_capture(self, height: int, width: int, bits: int) -> None:
        """Before capture starts (the service, once the sensor is open): allocate the CUDA
        backend's pinned buffer sets for (height, width) frames of `bits` bits, so the capture
        thread's first frame does not wait for the allocation.  No-op without a stager."""
        if self.stager is not None:
            self.stager.prepare((int(height), int(width)), np.uint8 if int(bits) <= 8 else np.uint16)

    # -- stages ---------------------------------------------------------------------------
    def despread(self, images: np.ndarray) -> np.ndarray:
        """(m * L, H, W) slot images -> (m, H, W) de-spread images (identity when L = 1).

        De-spread images are float32 own-light amplitudes normalised to [0, 1] of full scale
        (the decoder's convention for float input); rejected symbols are 0.
        """
        if self.source_bits is None:
            return images
        if self.foreign_sources:
            from edge.source.joint import joint_despread

            amplitude = joint_despread(images, self.profile.code.source, self.foreign_sources).amplitude
            return np.clip(amplitude / np.float32(self.full_scale), 0.0, 1.0, dtype=np.float32)
        from edge.source.matched_filter import despread

        amplitude = despread(images, self.profile.code.source).frames
        return np.clip(amplitude / np.float32(self.full_scale), 0.0, 1.0, dtype=np.float32)

    def split(self, frames: list[Frame] | tuple[Frame, ...]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Frames of one stack (schedule order) -> code frames (n, H, W), white (H, W), black (H, W)."""
        images = self.stacked(frames)
        return images[: self.n], images[self.n], images[self.n + 1]

    def stacked(self, frames: list[Frame] | tuple[Frame, ...]) -> np.ndarray:
        """Frames of one stack (schedule order) -> (n + 2, H, W): code frames, white, black (de-spread)."""
        self.check_schedule(frames)
        return self.despread(np.stack([f.image for f in frames]))

    def check_schedule(self, frames: list[Frame] | tuple[Frame, ...]) -> None:
        """ValueError unless the frames' projector frame ids follow the profile schedule."""
        ids = np.array([f.projector_frame for f in frames], dtype=np.int64)
        if ids.shape != self.schedule.shape or not np.array_equal(ids % (1 << 16), self.schedule % (1 << 16)):
            raise ValueError(
                f"stack frames must follow the profile schedule of {self.schedule.size} projector frames, "
                f"got ids {ids.tolist()[:8]}...")

    def decode(self, codes: np.ndarray, white: np.ndarray, black: np.ndarray):
        """`edge.decode.decode` with the profile's method, noise model, thresholds and disparity band
        (CUDA backend: only column, confidence and valid are downloaded; the other fields are None)."""
        return self._decode(codes, white, black, self.code, settings=self.settings,
                            **self._facts(codes.dtype == np.uint16))

    def _facts(self, uint16: bool) -> dict:
        p = self.profile
        return dict(min_disparity=p.decoder.min_disparity, max_disparity=p.decoder.max_disparity,
                    columns=self.columns, stripe=self.stripe, bit_depth=p.camera.bits if uint16 else None)

    def decode_staged_stack(self, stack: Stack):
        """The `Decoded` of `stack` from the frames the capture hook staged (`on_frame`), or None
        when it was not staged (the caller decodes the stack whole).  Same values as `decode`."""
        if self.stager is None:
            return None
        self.check_schedule(stack.frames)
        uint16 = self.stager.dtype == np.uint16
        return self.stager.decode_frames(stack.frames, self.code, self.settings, outputs=self._outputs,
                                         **self._facts(uint16))

    def warm_up(self) -> float:
        """Compile the decoder's numba kernels for this profile before capture starts.

        Decodes a small synthetic stack (8 rows x 64 columns, the camera's dtype, the profile's
        method and disparity band) so that the first real stack is not delayed by compilation
        (about two minutes with an empty cache on a 2-core machine, well under a second from the cache), and runs
        two EDC rounds on it (the check of the stack and a re-decode of its failing pixels: the
        sparse kernels of `edge.edc`, so ``edc.rounds`` can be switched on without a compile
        pause).  Returns the seconds spent.
        """
        t0 = time.perf_counter()
        dtype = np.uint8 if self.profile.camera.bits == 8 else np.uint16
        full = self.full_scale
        h, w = 8, 64
        mind, maxd = self.profile.decoder.min_disparity, self.profile.decoder.max_disparity
        x = np.arange(w)
        column = np.clip(x - (mind + maxd) // 2, 0, self.columns - 1) // self.stripe
        bits = self.code.codebook[column].T.astype(np.float64)  # (n, w)
        levels = self.code.q - 1
        codes = np.broadcast_to(0.1 * full + 0.7 * full * bits[:, None, :] / levels, (self.code.n, h, w))
        white = np.full((h, w), 0.8 * full)
        black = np.full((h, w), 0.1 * full)
        decoded = self.decode(codes.astype(dtype), white.astype(dtype), black.astype(dtype))
        if self.code.q == 2 and self.code.n <= 22:  # the EDC stage's kernels (edc.rounds may be switched on live)
            from .edc_stage import make_scan

            images = np.concatenate([codes, white[None], black[None]]).astype(dtype)
            checked = images.copy()
            checked[0, 0, :8] = images[self.n, 0, :8] - images[0, 0, :8] + images[self.n + 1, 0, :8]  # failing words
            # round 1 checks the stack; round 2 re-decodes the failing pixels, half of them fixed (its
            # own kernels: gather, pack at pixels, the nearest codewords of what fails again, the
            # neighbour support of what passes)
            again = checked.copy()
            again[:, 0, 4:8] = images[:, 0, 4:8]
            scan = make_scan(self, h, rounds=2)
            scan.run(lambda frames: checked if frames.shape[0] == checked.shape[0] else again[: frames.shape[0]],
                     guess=np.asarray(decoded.column, dtype=np.int32))
        return time.perf_counter() - t0

    def validity(self, decoded) -> np.ndarray:
        """(H, W) bool: the decoder's valid mask (it applies the profile's contrast and confidence
        thresholds) and a non-negative column."""
        return np.asarray(decoded.valid, dtype=bool) & (np.asarray(decoded.column) >= 0)

    def process(self, stack: Stack, masked_capture: MaskedCaptureFn | None = None) -> DepthResult:
        """Depth for one complete stack (see module docstring)."""
        t0 = time.perf_counter()
        images, stats = None, {}
        try:
            decoded = self.decode_staged_stack(stack) if self.stager is not None else None
            if decoded is None:
                images = self.stacked(stack.frames)
                cap = stack.coded(images, self.n, code=self.code, columns=self.columns, stripe=self.stripe,
                                  bit_depth=self.profile.camera.bits if images.dtype == np.uint16 else None)
                codes, white, black = cap.frames, cap.white, cap.black
                decoded = self.decode(codes, white, black)
        except NoPatternContrast:
            return self.empty_result(stack, t0)
        if self.stager is not None:  # CUDA: how the stack reached the device (summed in the service status)
            whole = int(images is not None)
            stats = {"gpu_stacks_staged": 1 - whole, "gpu_stacks_uploaded_whole": whole}
        valid = self.validity(decoded)
        column = np.where(valid, np.asarray(decoded.column, dtype=np.int32), np.int32(-1))
        confidence = np.asarray(decoded.confidence, dtype=np.float32)
        soft_column = column
        rounds, extra, round_ms, capture_ms = 0, (), (), ()
        if self.profile.edc.rounds > 0:
            images = self.stacked(stack.frames) if images is None else images
            edc = self.adaptive(stack, images, column, confidence, masked_capture)
            column, confidence, rounds, extra = edc.column, edc.confidence, edc.rounds, edc.extra
            round_ms, capture_ms = edc.round_ms, edc.capture_ms
            valid = column >= 0
        depth = column_to_depth_mm(column, self.geometry, stripe=self.stripe)
        error = None
        if getattr(decoded, "error", None) is not None:  # the decoder's P(wrong) of its own columns only
            error = error_image(decoded.error, (depth > 0) & (column == soft_column))
        fit = getattr(decoded, "stats", None) or {}
        noise = ((float(fit["noise_a"]), float(fit["noise_beta"]), bool(fit.get("noise_fitted")))
                 if "noise_a" in fit else None)
        return DepthResult(
            stack=stack.stack, sequence=stack.first_sequence, timestamp_ns=stack.timestamp_ns,
            received_ns=stack.received_ns, depth_mm=depth, confidence=confidence_to_u8(confidence, depth > 0),
            column=column, decode_s=time.perf_counter() - t0, edc_rounds=rounds, extra_frames=tuple(extra),
            edc_round_ms=tuple(round_ms), edc_capture_ms=tuple(capture_ms), stack_frames=len(stack.frames),
            stats=stats, error=error, noise=noise,
        )

    def empty_result(self, stack: Stack, t0: float) -> DepthResult:
        """The depth map of a stack in which no pixel sees the projector (`NoPatternContrast`: it is
        off or blocked, the lens is covered, every pixel saturates): every pixel invalid (depth 0,
        confidence 0, column -1; under the "error" rule an all-NaN error image, so that the error
        stream has every stack), no EDC round, and ``stats`` counts it as
        ``stacks_without_contrast`` (the service's status sums it and warns when such stacks begin)."""
        shape = np.shape(stack.frames[0].image)[:2]
        error = np.full(shape, np.nan, np.float32) if self.rule == "error" else None
        return DepthResult(
            stack=stack.stack, sequence=stack.first_sequence, timestamp_ns=stack.timestamp_ns,
            received_ns=stack.received_ns, depth_mm=np.zeros(shape, np.uint16), confidence=np.zeros(shape, np.uint8),
            column=np.full(shape, -1, np.int32), decode_s=time.perf_counter() - t0, stack_frames=len(stack.frames),
            stats={"stacks_without_contrast": 1}, error=error)

    def adaptive(self, stack, images, column, confidence, masked_capture):
        """EDC rounds (`edge.runtime.edc_stage.run_adaptive`) -> `EdcOutcome`."""
        from .edc_stage import run_adaptive

        return run_adaptive(self, stack, images, column, confidence, masked_capture)
