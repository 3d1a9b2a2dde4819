"""Error-detection maps (EDC): which pixels received a word that is not a codeword.

The one EDC check of the tree (`edge.edc` uses it too).  It is parameter-free: each sample is
binarised against the pixel's midpoint ``(white + black) / 2`` (`threshold`), or against its
inverse frame when one is given (N-ary codes: the nearest of q evenly spaced levels between black
and white), the word is packed with `edge.codes.words.pack_words` (frame 0 = least significant
bit) and looked up in the codebook (`edge.codes.words.columns_of_words`).  For a code with
minimum distance d_min every error pattern of weight 1..d_min-1 turns a codeword into a
non-codeword, so it is flagged; codes with d_min = 1 (Gray, binary, XOR) detect nothing.

Arithmetic: the midpoint is computed in float32 (float64 for float64 frames), the rule the EDC
kernels of `edge.edc._kernels` use, so the sparse kernels and this reference agree bit for bit.
"""

from __future__ import annotations

import numpy as np

from ..capture import CodedCapture, bit_depth_of, full_scale
from ..codes import Code
from ..codes.words import columns_of_words, pack_words
from .inputs import check_samples, codebook_rows, native, validate


def _work_dtype(*arrays: np.ndarray) -> type:
    return np.float64 if any(np.asarray(a).dtype == np.float64 for a in arrays) else np.float32


def threshold(white: np.ndarray, black: np.ndarray) -> np.ndarray:
    """(...) per-pixel binarisation threshold ``(white + black) / 2``: float32 (float64 when
    either is float64)."""
    dt = _work_dtype(white, black)
    return (np.asarray(white, dtype=dt) + np.asarray(black, dtype=dt)) * dt(0.5)


def hard_words(frames: np.ndarray, white: np.ndarray, black: np.ndarray,
               inverse: np.ndarray | None = None) -> np.ndarray:
    """Binarise (n, ...) frames and pack each pixel's word: uint64 (...), bit i = frame i.

    bit i = frames[i] > inverse[i] with inverse frames, else frames[i] > `threshold` (white, black).
    """
    f = np.asarray(frames)
    if inverse is not None:
        return pack_words(f > np.asarray(inverse), axis=0)
    dt = _work_dtype(f, white, black)
    t = threshold(white, black).astype(dt, copy=False)
    return pack_words(f.astype(dt, copy=False) > t, axis=0)


def lookup_columns(frames: np.ndarray, white: np.ndarray, black: np.ndarray, code: Code, *,
                   inverse: np.ndarray | None = None) -> np.ndarray:
    """Exact-membership hard decoding of a binary code: column (...) int32 of each pixel's
    `hard_words` word, -1 where it is no codeword (``< 0`` is the EDC error map).

    frames: (n, ...) samples (any real dtype); white, black: (...) calibration frames; inverse:
    optional (n, ...) inverse frames.
    """
    f = np.asarray(frames)
    if f.ndim < 1 or f.shape[0] != code.n:
        raise ValueError(f"code {code.name!r} needs {code.n} frames, got array of shape {f.shape}")
    if np.shape(white) != f.shape[1:] or np.shape(black) != f.shape[1:]:
        raise ValueError(
            f"white/black must have the frame shape {f.shape[1:]}, got {np.shape(white)} and {np.shape(black)}"
        )
    if code.q != 2:
        raise ValueError(f"EDC look-up needs a binary code, got {code.name!r} with q={code.q}")
    return columns_of_words(hard_words(f, white, black, inverse), code)


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

    frames (n, H, W), white/black (H, W), inverse (n, H, W) or None, as for `decode` (float frames
    in any scale: the decisions are midpoint thresholds).
    """
    st = validate(frames, white, black, code, inverse=inverse, scale_free=True)  # hard decisions
    ncols = codebook_rows(code, columns)
    if code.q == 2:
        col = columns_of_words(hard_words(st.frames, st.white, st.black, st.inverse), code)
        return ~((col >= 0) & (col < ncols))
    # N-ary: nearest level, then codebook membership of the base-q word (`pack_words`, q > 2).
    q, n = code.q, code.n
    if n * np.log2(q) > 62:
        raise ValueError(f"check: N-ary codes need q**n < 2**62, got q={q}, n={n}")
    a = st.white.astype(np.float64)
    b = st.black.astype(np.float64)
    span = np.where(a > b, a - b, 1.0)
    symbols = np.empty(st.frames.shape, dtype=np.int64)
    for i in range(n):
        if st.inverse is not None:
            x = ((st.frames[i] - st.inverse[i].astype(np.float64)) / span + 1.0) / 2.0
        else:
            x = (st.frames[i] - b) / span
        symbols[i] = np.clip(np.rint(x * (q - 1)), 0, q - 1).astype(np.int64)
    value = pack_words(symbols, q=q, axis=0)
    book = np.sort(pack_words(code.codebook[:ncols], q=q))
    pos = np.clip(np.searchsorted(book, value), 0, book.size - 1)
    return book[pos] != value


def check_capture(capture: CodedCapture, code: Code | None = None) -> np.ndarray:
    """`check` of a `edge.capture.CodedCapture` (its code unless ``code`` is given, its inverse
    frames and its ``columns``)."""
    code = capture.code if code is None else code
    if code is None:
        raise ValueError("check_capture: expected a code (the capture does not name one), got None")
    return check(capture.frames, capture.white, capture.black, code, inverse=capture.inverse,
                 columns=capture.columns)


def contrast_error_map(white: np.ndarray, black: np.ndarray, threshold: float, *,
                       bit_depth: int | None = None) -> np.ndarray:
    """(H, W) bool: True where white - black is below `threshold`.

    white, black: (H, W) calibration frames of one dtype, as for `decode` (uint8, uint16, or
    floats normalised to [0, 1]).  threshold is in normalised intensity: a fraction of the full
    scale `decode` reads them at (`edge.capture.full_scale` at `edge.capture.bit_depth_of`:
    255 for uint8, 2**bit_depth - 1 for uint16, where bit_depth None is detected as the smallest
    of 8, 10, 12, 14, 16 bits holding the largest value, so 12-bit data in uint16 is read at 4095;
    1 for floats), e.g. 40/255 reproduces OpenCV's default black threshold.
    """
    white = native(np.asarray(white))
    black = native(np.asarray(black))
    if white.shape != black.shape:
        raise ValueError(f"white/black: expected equal shapes, got {white.shape} and {black.shape}")
    arrays = [("white", white), ("black", black)]
    check_samples(arrays)
    scale = 1.0 / full_scale(white.dtype, bit_depth_of(arrays, bit_depth))
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
    bit_depth: int | None = None,
) -> np.ndarray:
    """(H, W) bool: `check` OR `contrast_error_map` (a pixel to re-project or discard); the
    arrays as for `decode` (the contrast at the bit depth `decode` reads the capture at)."""
    st = validate(frames, white, black, code, inverse=inverse, bit_depth=bit_depth)
    return check(st.frames, st.white, st.black, code, inverse=st.inverse, columns=columns) | contrast_error_map(
        st.white, st.black, contrast_threshold, bit_depth=st.bit_depth
    )
