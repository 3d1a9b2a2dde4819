"""Error-detection maps (EDC): which pixels received a word that is not a codeword.

`check` is parameter-free: each sample is binarised against the pixel's (white + black)/2, or
against its inverse frame when one is given (N-ary codes: the nearest of q evenly spaced levels
between black and white), and the received word is looked up in the codebook.  For a code with
minimum distance d_min every error pattern of weight 1..d_min-1 turns a codeword into a
non-codeword, so it is flagged; codes with d_min = 1 (Gray, binary, XOR) detect nothing.
"""

from __future__ import annotations

import numpy as np

from ..codes import Code
from .inputs import validate
from .tables import _compress, code_tables


def _binary_words(frames: np.ndarray, white: np.ndarray, black: np.ndarray,
                  inverse: np.ndarray | None) -> np.ndarray:
    words = np.zeros(frames.shape[1:], dtype=np.uint64)
    if inverse is None:
        thr = 0.5 * (white.astype(np.float64) + black.astype(np.float64))
    for i in range(frames.shape[0]):
        bit = frames[i] > inverse[i] if inverse is not None else frames[i] > thr
        words |= bit.astype(np.uint64) << np.uint64(i)
    return words


def check(
    frames: np.ndarray,
    white: np.ndarray,
    black: np.ndarray,
    code: Code,
    *,
    inverse: np.ndarray | None = None,
    columns: int | None = None,
) -> np.ndarray:
    """(H, W) bool error map: True where the hard-decision word is not a codeword of `code`
    (or is the codeword of a column >= `columns`, the codebook rows the projector does not use).

    frames (n, H, W), white/black (H, W), inverse (n, H, W) or None, as for `decode`.
    """
    st = validate(frames, white, black, code, inverse=inverse)
    ncols = code.size if columns is None else int(columns)
    tb = code_tables(code)
    if code.q == 2:
        words = _binary_words(st.frames, st.white, st.black, st.inverse)
        if tb.has_info:
            col = tb.col_of_info[_compress(words.ravel(), tb.comp_info)].reshape(words.shape)
            ok = (col >= 0) & (tb.masks[np.maximum(col, 0)] == words) & (col < ncols)
        else:
            used = tb.masks[:ncols]
            ok = np.isin(words, used)
        return ~ok
    # N-ary: nearest level, then codebook membership by base-q integer.
    q, n = code.q, code.n
    if n * np.log2(q) > 62:
        raise ValueError(f"check: N-ary codes need q**n < 2**62, got q={q}, n={n}")
    a = st.white.astype(np.float64)
    b = st.black.astype(np.float64)
    span = np.where(a > b, a - b, 1.0)
    value = np.zeros(st.frames.shape[1:], dtype=np.int64)
    for i in range(n):
        if st.inverse is not None:
            x = ((st.frames[i] - st.inverse[i].astype(np.float64)) / span + 1.0) / 2.0
        else:
            x = (st.frames[i] - b) / span
        sym = np.clip(np.rint(x * (q - 1)), 0, q - 1).astype(np.int64)
        value = value * q + sym
    powers = q ** np.arange(n - 1, -1, -1, dtype=np.int64)
    book = np.sort(code.codebook[:ncols].astype(np.int64) @ powers)
    pos = np.clip(np.searchsorted(book, value), 0, book.size - 1)
    return book[pos] != value


def contrast_error_map(white: np.ndarray, black: np.ndarray, threshold: float) -> np.ndarray:
    """(H, W) bool: True where white - black is below `threshold`.

    threshold is in normalised intensity (fraction of full scale: 255 for uint8, 65535 for
    uint16, 1 for floats), e.g. 40/255 reproduces OpenCV's default black threshold.
    """
    white = np.asarray(white)
    black = np.asarray(black)
    if white.shape != black.shape:
        raise ValueError(f"white/black: expected equal shapes, got {white.shape} and {black.shape}")
    scale = {np.dtype(np.uint8): 1 / 255, np.dtype(np.uint16): 1 / 65535}.get(white.dtype, 1.0)
    return (white.astype(np.float64) - black.astype(np.float64)) * scale < threshold


def error_map(
    frames: np.ndarray,
    white: np.ndarray,
    black: np.ndarray,
    code: Code,
    *,
    contrast_threshold: float = 0.04,
    inverse: np.ndarray | None = None,
    columns: int | None = None,
) -> np.ndarray:
    """(H, W) bool: `check` OR `contrast_error_map` (a pixel to re-project or discard)."""
    return check(frames, white, black, code, inverse=inverse, columns=columns) | contrast_error_map(
        white, black, contrast_threshold
    )
