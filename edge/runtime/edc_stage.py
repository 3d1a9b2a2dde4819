"""The adaptive EDC stage of `DepthPipeline` (profile ``edc.rounds`` > 0), on `edge.edc.AdaptiveScan`.

Round 1 is the stack the service already captured (code frames, white, black): the scan checks
every pixel's hard word against the codebook (CRC / syndrome check) and fixes the ones that pass.
Each further round (at most ``edc.rounds``) asks the sensor for the scan's next masked frames
(``masked_capture(stack, round, frames)``: n masked patterns + a masked white, projector frame ids
carrying the round number) and re-decodes only the failing pixels.

Output: the scan's column map (pixels never resolved are invalid: their error was detected but
not corrected) and the soft decoder's confidence where valid.  Without a masked-capture path (a
backend that cannot re-project) the stage runs round 1 only, i.e. the EDC check invalidates
detected errors.
"""

from __future__ import annotations

from typing import Any

import numpy as np


def run_adaptive(pipeline: Any, stack: Any, codes: np.ndarray, white: np.ndarray, black: np.ndarray,
                 column: np.ndarray, confidence: np.ndarray, masked_capture: Any):
    """-> (column (H, W) int32, confidence (H, W) float32, rounds run, masked frames captured)."""
    from edge.edc import AdaptiveScan

    p = pipeline.profile
    h = codes.shape[1]
    scan = AdaptiveScan(pipeline.code, p.projector.width, h, stripe=pipeline.stripe,
                        max_rounds=1 + int(p.edc.rounds), binarisation="calibrated",
                        min_contrast=min(p.decoder.min_contrast, 0.999),
                        noise=(p.camera.sigma_r, p.camera.sigma_s),
                        full_scale=pipeline.full_scale,
                        disparity_band=(p.decoder.min_disparity, p.decoder.max_disparity))
    scan.start()
    scan.update(np.concatenate([codes, white[None], black[None]]))
    extra = []
    edc_round = 1
    while masked_capture is not None:
        frames = scan.next_frames()
        if frames is None:
            break
        captured = masked_capture(stack.stack, edc_round, frames)
        extra.extend(captured)
        scan.update(np.stack([f.image for f in captured]))
        edc_round += 1
    result = scan.result()
    col = np.asarray(result.column, dtype=np.int32)
    conf = np.where(col >= 0, confidence, np.float32(0)).astype(np.float32)
    return col, conf, len(result.rounds), extra
