"""Hard decisions and exact codebook membership: the parameter-free EDC check.

A camera pixel's n samples are binarised against the midpoint of its calibration frames,
``bit_i = frame_i > (white + black) / 2``; the resulting word either IS a codeword (the check
passes and the codeword's index is the pixel's column) or it is not (an error is detected).  For a
code of minimum distance d_min every pattern of 1 .. d_min-1 bit errors turns a codeword into a
non-codeword, so it is always detected; a burst of errors is missed only if it happens to land
exactly on another codeword (probability about 2**-(n-k) for random words).

Membership is one table look-up per pixel: the binarised word packed into an integer (frame 0 =
most significant bit) indexes a (2**n,) int32 table holding the codeword's column or -1.
"""

from __future__ import annotations

import functools

import numpy as np

from edge.codes import Code

#: Longest code for which the (2**n,) membership table is built (16 MiB of int32 at n = 22).
MAX_TABLE_BITS = 22


@functools.lru_cache(maxsize=32)
def _table(code: Code) -> np.ndarray:
    if code.q != 2:
        raise ValueError(f"EDC look-up needs a binary code, got {code.name!r} with q={code.q}")
    if code.n > MAX_TABLE_BITS:
        raise ValueError(f"EDC look-up supports n <= {MAX_TABLE_BITS} frames, got {code.name!r} with n={code.n}")
    weights = np.left_shift(1, np.arange(code.n - 1, -1, -1, dtype=np.int64))
    words = code.codebook.astype(np.int64) @ weights
    table = np.full(1 << code.n, -1, dtype=np.int32)
    # a word sent by several columns (d_min = 0) is ambiguous: it stays -1 except for its first column
    table[words[::-1]] = np.arange(code.size - 1, -1, -1, dtype=np.int32)
    table.setflags(write=False)
    return table


@functools.lru_cache(maxsize=32)
def _packed(code: Code) -> np.ndarray:
    weights = np.left_shift(1, np.arange(code.n - 1, -1, -1, dtype=np.int64))
    words = code.codebook.astype(np.int64) @ weights
    words.setflags(write=False)
    return words


def packed_codewords(code: Code) -> np.ndarray:
    """(size,) int64 codeword of each column packed like `membership_table` (frame 0 = MSB)."""
    return _packed(code)


def membership_table(code: Code) -> np.ndarray:
    """(2**n,) int32: column whose codeword packs to each integer (frame 0 = MSB), -1 if none."""
    return _table(code)


def threshold(white: np.ndarray, black: np.ndarray) -> np.ndarray:
    """(H, W) float32 per-pixel binarisation threshold ``(white + black) / 2``."""
    return (np.asarray(white, dtype=np.float32) + np.asarray(black, dtype=np.float32)) * np.float32(0.5)


def pack_bits(frames: np.ndarray, thresh: np.ndarray) -> np.ndarray:
    """Binarise (n, ...) frames against ``thresh`` (...) and pack: int64 (...), frame 0 = MSB."""
    f = np.asarray(frames)
    t = np.asarray(thresh, dtype=np.float32)
    word = np.zeros(f.shape[1:], dtype=np.int64)
    for i in range(f.shape[0]):
        word = (word << 1) | (f[i].astype(np.float32) > t)
    return word


def lookup_columns(frames: np.ndarray, white: np.ndarray, black: np.ndarray, code: Code) -> np.ndarray:
    """Exact-membership hard decoding: column (...) int32 of the binarised word, -1 if it is no codeword.

    frames: (n, ...) samples (any real dtype); white, black: (...) calibration frames.
    ``lookup_columns(...) < 0`` is the EDC error map (parameter-free).
    """
    f = np.asarray(frames)
    if f.ndim < 1 or f.shape[0] != code.n:
        raise ValueError(f"code {code.name!r} needs {code.n} frames, got array of shape {f.shape}")
    if np.shape(white) != f.shape[1:] or np.shape(black) != f.shape[1:]:
        raise ValueError(
            f"white/black must have the frame shape {f.shape[1:]}, got {np.shape(white)} and {np.shape(black)}"
        )
    return _table(code)[pack_bits(f, threshold(white, black))]
