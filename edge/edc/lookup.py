"""Hard decisions and exact codebook membership: the parameter-free EDC check, as `edge.edc` uses it.

A camera pixel's n samples are binarised against the midpoint of its calibration frames,
``bit_i = frame_i > (white + black) / 2``; the resulting word either IS a codeword (the check
passes and the codeword's index is the pixel's column) or it is not (an error is detected).  For a
code of minimum distance d_min every pattern of 1 .. d_min-1 bit errors turns a codeword into a
non-codeword, so it is always detected; a burst of errors is missed only if it happens to land
exactly on another codeword (probability about 2**-(n-k) for random words).

The check has one implementation, `edge.decode.check` (`lookup_columns`, `threshold`); the words
and the membership table have one, `edge.codes.words` (bit i = frame i, frame 0 = least
significant bit).  This module names them for the EDC loop and adds `pack_bits` (binarise
against a given threshold), the numpy reference of the `edge.edc._kernels` packers.
"""

from __future__ import annotations

import numpy as np

from edge.codes.words import MAX_TABLE_BITS, membership_table, pack_words, packed_codewords
from edge.decode.check import lookup_columns, threshold

__all__ = ["MAX_TABLE_BITS", "lookup_columns", "membership_table", "pack_bits", "packed_codewords", "threshold"]


def pack_bits(frames: np.ndarray, thresh: np.ndarray) -> np.ndarray:
    """Binarise (n, ...) frames against ``thresh`` (...) in float32 and pack (`pack_words`): int64 (...)."""
    f = np.asarray(frames).astype(np.float32)
    return pack_words(f > np.asarray(thresh, dtype=np.float32), axis=0).astype(np.int64)
