"""What an adaptive round projects and how a pixel passes: the EDC scheme (one CRC code).

A *scheme* is the per-round pattern set of an adaptive structured-light loop plus its per-pixel
acceptance rule.  `AdaptiveScan` drives any object with this interface:

    name: str                      -- printed in reports
    n_frames: int                  -- pattern frames per round (calibration frames not included)
    codes: tuple[Code, ...]        -- the codes projected, in order
    profiles(projector_width, stripe) -> (n_frames, projector_width) float32 in [0, 1]
    decide(frames, white, black) -> (column int32 (P,), passed bool (P,))

and optionally the sparse fast path the loop prefers when present:

    decide_at(frames, ys, xs, hi, lo) -> (column int32 (P,), passed bool (P,), guess int32 (P,))

``frames`` is (n_frames, P) samples of P camera pixels, ``white``/``black`` (P,) their
calibration samples.  ``decide_at`` reads the samples of the P open pixels ``(ys, xs)`` straight
from the (m, H, W) round frames (no gather of the full frame) and also returns each pixel's best
GUESS (the nearest codeword of a failing word; the ensemble's majority column): the column a
conventional single pass would report, which the loop may keep where verified neighbours support
it.  `EdcScheme` accepts a pixel when its binarised word is a codeword (the
parameter-free CRC check); `edge.edc.gupta.EnsembleScheme` accepts it when two of four codes agree.
"""

from __future__ import annotations

import numpy as np

from edge.codes import Code, get_code

from . import _kernels
from .lookup import lookup_columns, membership_table, packed_codewords


def code_profiles(code: Code, projector_width: int, stripe: int) -> np.ndarray:
    """(n, projector_width) float32 0/1: projector column x sends codebook row x // stripe (dark beyond)."""
    rows = np.arange(projector_width) // stripe
    covered = rows < code.size
    out = np.zeros((code.n, projector_width), dtype=np.float32)
    out[:, covered] = code.codebook[rows[covered]].T
    return out


def unmeasurable_columns(scheme) -> np.ndarray:
    """(size,) bool: columns whose word over all of the scheme's frames is constant (all 0 or all 1).

    Binarising a pixel against the midpoint of its own extreme samples (self-calibrated mode)
    always yields a word with a 0 and a 1, so these columns can never be decoded in that mode.
    For xor02-10+crc5 and gray-10+crc5 it is column 0 alone (the all-zero codeword; CRC 0x15 has
    the factor x + 1, so no codeword has odd weight and the all-one word of 15 bits is none).
    """
    words = np.concatenate([c.codebook for c in scheme.codes], axis=1)
    ones = words.sum(axis=1)
    return (ones == 0) | (ones == words.shape[1])


class EdcScheme:
    """One systematic code with error-detecting redundancy (e.g. ``xor02-10+crc5``).

    A pixel passes when its hard-decision word is exactly a codeword; its column is that
    codeword's index.  Every pattern of fewer than d_min bit errors is detected.
    """

    def __init__(self, code: Code | str) -> None:
        c = get_code(code) if isinstance(code, str) else code
        if not isinstance(c, Code):
            raise ValueError(f"EdcScheme needs an edge.codes.Code or a code name, got {type(code).__name__}")
        membership_table(c)  # validates binary and n <= MAX_TABLE_BITS
        if c.d_min < 2:
            raise ValueError(f"EDC needs a code that detects errors (d_min >= 2), got {c.name!r} with d_min "
                             f"{c.d_min}: every word is a codeword, so every pixel would pass unchecked")
        self.code = c
        self.codes = (c,)
        self.name = c.name
        self.n_frames = c.n

    def profiles(self, projector_width: int, stripe: int) -> np.ndarray:
        return code_profiles(self.code, projector_width, stripe)

    def decide(self, frames: np.ndarray, white: np.ndarray, black: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        column = lookup_columns(frames, white, black, self.code)
        return column, column >= 0

    def decide_at(self, frames: np.ndarray, ys: np.ndarray, xs: np.ndarray, hi: np.ndarray, lo: np.ndarray,
                  start: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Sparse `decide` over the pixels (ys, xs) of (m, H, W) ``frames`` (code frames from ``start``).

        hi, lo: (P,) float32 levels whose midpoint is the threshold.  Returns (column, passed, guess):
        guess = column where passed, else the nearest codeword in Hamming distance.
        """
        return self._decide_words(_kernels.pack_words_at(frames, int(start), self.code.n, ys, xs, hi, lo))

    def decide_full(self, frames: np.ndarray, hi: np.ndarray, lo: np.ndarray, ys: np.ndarray, xs: np.ndarray,
                    start: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """`decide_at` for round 1: hi, lo are (H, W) images, the words of the whole frame are packed at once."""
        return self._decide_words(_kernels.pack_words_full(frames, int(start), self.code.n, hi, lo)[ys, xs])

    def _decide_words(self, words: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        column = membership_table(self.code)[words]
        passed = column >= 0
        guess = column.copy()
        bad = np.nonzero(~passed)[0]
        if bad.size:
            guess[bad] = _kernels.nearest_codewords(words[bad], packed_codewords(self.code))
        return column.astype(np.int32), passed, guess.astype(np.int32)

    def __repr__(self) -> str:
        return f"EdcScheme({self.code!r})"
