"""Gupta et al. (CVPR 2011) ensemble baseline: four codes decoded separately, accept where two agree.

"Structured light 3D scanning in the presence of global illumination": project four 10-bit codes
designed for different light-transport regimes -- conventional (reflected) Gray, max-min-SW Gray
(long minimum stripe width, robust to defocus and long-range effects), XOR-04 and XOR-02 (all
frames high-frequency, robust to short-range effects) -- decode each on its own by binarisation,
and accept a camera pixel where at least two codes give the same column.  Every k-bit word is a
codeword of each code, so none of them can detect an error alone; agreement is the check.

Frames per iteration: 4 x 10 pattern frames (+ calibration: white and black in the first
iteration, a masked white afterwards, exactly like the EDC loop).  The adaptive iteration uses
the same `AdaptiveScan` masking rule as the EDC loop, so frames spent and errors left compare
like for like.
"""

from __future__ import annotations

import numpy as np

from edge.codes import Code, get_code

from .lookup import lookup_columns
from .scheme import code_profiles


def gupta_codes(k: int = 10) -> tuple[Code, ...]:
    """The four codes of the ensemble: gray-k, maxminsw-k, xor04-k, xor02-k."""
    from .maxminsw import maxminsw_code

    return (get_code(f"gray-{k}"), maxminsw_code(k), get_code(f"xor04-{k}"), get_code(f"xor02-{k}"))


def ensemble_vote(columns: np.ndarray, min_agree: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """Combine per-code columns (c, P) int: column (P,) int32 and accepted (P,) bool.

    A pixel is accepted when some column value is given by at least ``min_agree`` codes and no
    other value has as many votes (a 2-2 split is ambiguous and rejected).  Negative entries
    (no decision) never vote.
    """
    cols = np.asarray(columns)
    if cols.ndim != 2 or cols.shape[0] < 2:
        raise ValueError(f"ensemble_vote needs (codes >= 2, P) columns, got shape {cols.shape}")
    if not 1 <= min_agree <= cols.shape[0]:
        raise ValueError(f"min_agree must be in 1..{cols.shape[0]}, got {min_agree}")
    valid = cols >= 0
    votes = ((cols[:, None, :] == cols[None, :, :]) & valid[:, None, :] & valid[None, :, :]).sum(axis=1)
    votes = np.where(valid, votes, 0)  # votes[i, p]: codes agreeing with code i at pixel p
    best = votes.argmax(axis=0)
    p = np.arange(cols.shape[1])
    top = votes[best, p]
    column = cols[best, p].astype(np.int32)
    rival = ((votes == top[None]) & (cols != column[None])).any(axis=0)
    accepted = (top >= min_agree) & ~rival
    return np.where(accepted, column, -1).astype(np.int32), accepted


def majority_column(columns: np.ndarray) -> np.ndarray:
    """(P,) int32: the column most codes give (ties: the earliest code's); what an unchecked pass reports."""
    stack = np.asarray(columns)
    votes = ((stack[:, None, :] == stack[None, :, :]) & (stack[None, :, :] >= 0)).sum(axis=1)
    return stack[votes.argmax(axis=0), np.arange(stack.shape[1])].astype(np.int32)


class EnsembleScheme:
    """Scheme for `AdaptiveScan`: project several codes back to back, accept where ``min_agree`` agree."""

    def __init__(self, codes: tuple[Code, ...] | None = None, *, min_agree: int = 2, name: str = "gupta-ensemble") -> None:
        self.codes = tuple(codes) if codes is not None else gupta_codes(10)
        if len(self.codes) < 2:
            raise ValueError(f"an ensemble needs at least two codes, got {len(self.codes)}")
        sizes = {c.size for c in self.codes}
        if len(sizes) != 1:
            raise ValueError(f"ensemble codes must distinguish the same number of columns, got sizes {sorted(sizes)}")
        self.min_agree = int(min_agree)
        self.name = name
        self.n_frames = int(sum(c.n for c in self.codes))

    def profiles(self, projector_width: int, stripe: int) -> np.ndarray:
        return np.concatenate([code_profiles(c, projector_width, stripe) for c in self.codes], axis=0)

    def decide(self, frames: np.ndarray, white: np.ndarray, black: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        cols = []
        start = 0
        for c in self.codes:
            cols.append(lookup_columns(frames[start:start + c.n], white, black, c))
            start += c.n
        return ensemble_vote(np.stack(cols), self.min_agree)

    def decide_at(self, frames: np.ndarray, ys: np.ndarray, xs: np.ndarray, hi: np.ndarray, lo: np.ndarray,
                  start: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Sparse `decide` (see `edge.edc.scheme`); guess = the majority column (ties: the first code)."""
        from . import _kernels

        return self._vote([_kernels.pack_words_at(frames, int(s), c.n, ys, xs, hi, lo)
                           for c, s in zip(self.codes, self._starts(start))])

    def decide_full(self, frames: np.ndarray, hi: np.ndarray, lo: np.ndarray, ys: np.ndarray, xs: np.ndarray,
                    start: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """`decide_at` for round 1 with (H, W) level images."""
        from . import _kernels

        return self._vote([_kernels.pack_words_full(frames, int(s), c.n, hi, lo)[ys, xs]
                           for c, s in zip(self.codes, self._starts(start))])

    def _starts(self, start: int) -> list[int]:
        return list(start + np.cumsum([0] + [c.n for c in self.codes[:-1]]))

    def _vote(self, words: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        from .lookup import membership_table

        stack = np.stack([membership_table(c)[w] for c, w in zip(self.codes, words)])
        column, passed = ensemble_vote(stack, self.min_agree)
        guess = majority_column(stack)
        return column, passed, np.where(passed, column, guess).astype(np.int32)

    def __repr__(self) -> str:
        return f"EnsembleScheme({[c.name for c in self.codes]}, min_agree={self.min_agree})"
