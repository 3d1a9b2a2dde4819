"""Light-source codes (paper section 5): each "on" of a projection becomes a device-specific bit string.

A `SourceCode` is a binary string ``bits`` of length L (slot 0 first).  A device spreads every
projection symbol over L slots: an "on" sends ``bits``, an "off" sends L dark slots (``off="dark"``,
the default) or the complement ``1 - bits`` (``off="complement"``).  A matched filter
(`edge.source.matched_filter`) then keeps only light that follows ``bits``.

Why "dark" is the default for an "off": it keeps the device's optical duty cycle and eye-safety budget
equal to the uncoded device per "on"; the matched filter's zero-mean template already removes the
constant ambient, so no complement is needed for balanced detection; and a pixel that the device never
lights then carries no own light at all, so any correlated light there is foreign and is rejected.
``"complement"`` doubles the signal (antipodal, +-A instead of A/0) at the price of lighting every
pixel all the time; both are supported.

Correlation measures used throughout (all exact, over every phase a foreign device can have):

* **frame sensors** (intensity per slot): Pearson correlation between the zero-mean template
  ``bits - mean(bits)`` and the L received slot values.  Constant ambient gives 0.
* **event sensors** (signed event counts per slot): cosine similarity between the code's cyclic
  transition sequence ``bits[i] - bits[i-1]`` and the signed event counts.  Static light gives no
  events at all.

A foreign device is unsynchronised: my L-slot window sees the tail of one of its symbols and the head
of the next, each "on" or "off", at any integer or fractional slot offset.  `interference_windows`
enumerates exactly these windows; `worst_interference` is the largest correlation any of them reaches
against my template.  `family` searches all binary necklaces of length L for N codes whose pairwise
worst case is smallest (exhaustive over necklace classes, clique search over the threshold), because
the Walsh/Gold cross-correlation bounds are periodic-only and say nothing about the on/off (aperiodic)
and fractional windows that unsynchronised SL devices produce.
"""

from __future__ import annotations

import functools
import itertools
import warnings
from dataclasses import dataclass, field
from typing import Iterable, Sequence

import numpy as np

#: Codes named in the paper (section 5).
PAPER_CODES: dict[str, str] = {
    "paper-1101": "1101",
    "paper-1010": "1010",
    "paper-10100010": "10100010",
    "paper-1100": "1100",
    "paper-0101": "0101",
}

#: Longest code `family` searches exhaustively (necklaces of length L: about 2**L / L candidates).
MAX_SEARCH_LENGTH = 12

OFF_MODES = ("dark", "complement")


@dataclass(frozen=True, eq=False)
class SourceCode:
    """A device's light-source code.

    Attributes:
        bits: uint8 (L,) 0/1, slot 0 first; at least one 1 and one 0.
        name: label (defaults to the bit string).
    """

    bits: np.ndarray
    name: str = ""
    _key: str = field(init=False, repr=False)

    def __post_init__(self) -> None:
        raw = np.asarray(self.bits)
        if raw.ndim != 1:
            raise ValueError(f"source code bits must be 1-D (L,), got shape {raw.shape}")
        if raw.size == 0:
            raise ValueError("source code must have length L >= 2, got length 0")
        if not np.all((raw == 0) | (raw == 1)):
            raise ValueError(f"source code bits must be 0/1, got {raw.tolist()}")
        b = raw.astype(np.uint8)
        if b.sum() == 0:
            raise ValueError(f"source code {_bits_str(b)!r} has no 'on' slot; need at least one 1 and one 0")
        if b.sum() == b.size:
            raise ValueError(f"source code {_bits_str(b)!r} has no 'off' slot; need at least one 1 and one 0")
        b = np.ascontiguousarray(b)
        b.setflags(write=False)
        object.__setattr__(self, "bits", b)
        object.__setattr__(self, "_key", _bits_str(b))
        if not self.name:
            object.__setattr__(self, "name", self._key)

    @property
    def length(self) -> int:
        """L, the number of slots one projection symbol becomes."""
        return int(self.bits.size)

    @property
    def weight(self) -> int:
        """Number of "on" slots."""
        return int(self.bits.sum())

    @property
    def string(self) -> str:
        """The bits as a string, e.g. ``"1101"``."""
        return self._key

    @property
    def template(self) -> np.ndarray:
        """float64 (L,) zero-mean matched-filter template ``bits - weight / L``."""
        return self.bits.astype(np.float64) - self.weight / self.length

    @property
    def transitions(self) -> np.ndarray:
        """int8 (L,) cyclic transition sequence ``bits[i] - bits[i-1]`` (+1 = on edge, -1 = off edge):
        the polarity of the events an event camera sees at the start of slot i."""
        b = self.bits.astype(np.int8)
        return (b - np.roll(b, 1)).astype(np.int8)

    def rotations(self) -> list[str]:
        return [_bits_str(np.roll(self.bits, -k)) for k in range(self.length)]

    def __eq__(self, other: object) -> bool:
        return isinstance(other, SourceCode) and other._key == self._key

    def __hash__(self) -> int:
        return hash(self._key)

    def __repr__(self) -> str:
        extra = f", name={self.name!r}" if self.name != self._key else ""
        return f"SourceCode({self._key!r}{extra})"


def _bits_str(bits: np.ndarray) -> str:
    return "".join(str(int(v)) for v in bits)


def source_code(spec: "str | Sequence[int] | np.ndarray | SourceCode", name: str = "") -> SourceCode:
    """A `SourceCode` from ``"1101"``, a paper name (``"paper-1101"``), a 0/1 sequence or a SourceCode."""
    if isinstance(spec, SourceCode):
        return spec if not name else SourceCode(spec.bits, name)
    if isinstance(spec, str):
        text = PAPER_CODES.get(spec, spec).strip()
        if text == "":
            raise ValueError("source code must have length L >= 2, got an empty string")
        if set(text) - {"0", "1"}:
            raise ValueError(f"source code must be a string of 0/1, got {spec!r}")
        return SourceCode(np.array([int(ch) for ch in text], dtype=np.uint8), name or spec)
    return SourceCode(np.asarray(spec), name)


# --------------------------------------------------------------------------------------------
# Correlations
# --------------------------------------------------------------------------------------------

def correlation(code: SourceCode, windows: np.ndarray, kind: str = "frame") -> np.ndarray:
    """Normalised correlation of received windows with a code.

    windows: (..., L) float.  kind ``"frame"``: slot intensities, Pearson correlation with the
    zero-mean template; ``"event"``: signed event counts per slot, cosine with `transitions`.
    Returns float64 (...,) in [-1, 1]; 0 where a window carries no signal (constant / no events).
    """
    w = np.asarray(windows, dtype=np.float64)
    if w.shape[-1] != code.length:
        raise ValueError(f"windows must end in L={code.length} slots, got shape {w.shape}")
    if kind == "frame":
        s = code.template
        w = w - w.mean(axis=-1, keepdims=True)
    elif kind == "event":
        s = code.transitions.astype(np.float64)
    else:
        raise ValueError(f"kind must be 'frame' or 'event', got {kind!r}")
    num = w @ s
    den = np.linalg.norm(s) * np.linalg.norm(w, axis=-1)
    out = np.zeros_like(num)
    ok = den > 1e-12 * max(1.0, float(np.abs(w).max(initial=0.0)))
    np.divide(num, den, out=out, where=ok)
    return out


def periodic_correlation(a: SourceCode, b: SourceCode, kind: str = "frame") -> np.ndarray:
    """(L,) correlation of code a's template with b shifted cyclically by k slots, k = 0..L-1
    (b "on" in every symbol, i.e. the periodic case).  ``a is b`` gives the autocorrelation."""
    if a.length != b.length:
        raise ValueError(f"periodic correlation needs equal lengths, got {a.length} and {b.length}")
    rolled = np.stack([np.roll(b.bits, -k) for k in range(b.length)]).astype(np.float64)
    if kind == "event":
        rolled = rolled - np.roll(rolled, 1, axis=1)
    return correlation(a, rolled, kind)


def interference_windows(
    foreign: SourceCode, length: int, *, fractions: int = 4, kind: str = "frame", slot_ratio: float = 1.0
) -> np.ndarray:
    """Every window of ``length`` slots that an unsynchronised foreign device can put on my slots.

    The foreign device sends its code for "on" and dark slots for "off", in any order; my window
    starts at any offset into its stream, in steps of ``1 / fractions`` of my slot (a slot that
    straddles two foreign slots receives their overlap-weighted mix).  ``slot_ratio`` is the foreign
    slot duration divided by mine (1 = same slot rate).

    Returns float64 (K, length): mean foreign intensity in each of my slots (``kind="frame"``) or the
    signed number of foreign on/off edges inside each of my slots (``kind="event"``); duplicates
    removed, windows without signal dropped.
    """
    if length < 1:
        raise ValueError(f"window length must be >= 1 slot, got {length}")
    if fractions < 1:
        raise ValueError(f"fractions must be >= 1, got {fractions}")
    if slot_ratio <= 0:
        raise ValueError(f"slot_ratio must be > 0, got {slot_ratio}")
    if kind not in ("frame", "event"):
        raise ValueError(f"kind must be 'frame' or 'event', got {kind!r}")
    fl = foreign.length
    sym_time = fl * slot_ratio  # one foreign symbol, in my slots
    nsym = int(np.ceil((length + 1) / sym_time)) + 2
    starts = sym_time + np.arange(int(np.ceil(sym_time * fractions))) / fractions
    t = starts[:, None] + np.arange(length + 1)[None, :]  # (S, L+1) my slot edges
    out = []
    for states in itertools.product((0, 1), repeat=nsym):
        if not any(states):
            continue
        stream = np.concatenate([foreign.bits if s else np.zeros(fl, np.uint8) for s in states]).astype(np.float64)
        if kind == "frame":
            cum = np.concatenate([[0.0], np.cumsum(stream)]) * slot_ratio
            integral = np.interp(t / slot_ratio, np.arange(cum.size), cum)
            out.append(np.diff(integral, axis=1))
        else:
            edges = np.diff(stream)  # edge k+1 at time (k+1) * slot_ratio
            times = (np.arange(edges.size) + 1) * slot_ratio
            bins = np.floor(times[None, :] - starts[:, None] + 1e-9).astype(np.int64)  # (S, E)
            win = np.zeros((starts.size, length))
            for s_idx in range(starts.size):
                ok = (bins[s_idx] >= 0) & (bins[s_idx] < length) & (edges != 0)
                np.add.at(win[s_idx], bins[s_idx][ok], edges[ok])
            out.append(win)
    arr = np.unique(np.round(np.concatenate(out), 12), axis=0)
    keep = np.abs(arr).sum(axis=1) > 1e-12
    if kind == "frame":
        keep &= np.ptp(arr, axis=1) > 1e-12
    return arr[keep]


def worst_interference(mine: SourceCode, foreign: SourceCode, *, kind: str = "frame", fractions: int = 4) -> float:
    """Largest correlation any unsynchronised window of ``foreign`` reaches against ``mine``
    (the quantity the acceptance threshold must exceed for the foreign light to be rejected)."""
    w = interference_windows(foreign, mine.length, fractions=fractions, kind=kind)
    return float(correlation(mine, w, kind).max(initial=0.0))


# --------------------------------------------------------------------------------------------
# Families
# --------------------------------------------------------------------------------------------

def necklaces(length: int) -> list[SourceCode]:
    """One representative (the smallest rotation) of every binary necklace of ``length`` with at
    least one 1 and one 0, primitive (period = length) necklaces only."""
    if length < 2:
        raise ValueError(f"source codes need length L >= 2, got {length}")
    out = []
    seen = set()
    for v in range(1, 2**length - 1):
        s = format(v, f"0{length}b")
        rots = [s[k:] + s[:k] for k in range(length)]
        rep = min(rots)
        if rep in seen:
            continue
        seen.add(rep)
        if len(set(rots)) != length:
            continue  # periodic with a shorter period: a shifted copy of itself
        out.append(source_code(rep))
    return out


def worst_interference_matrix(codes: Sequence[SourceCode], kind: str = "frame", fractions: int = 2) -> np.ndarray:
    """(N, N) float64: entry [i, j] = `worst_interference(codes[i], codes[j])` (i != j), diagonal =
    largest periodic autocorrelation sidelobe of codes[i]."""
    n = len(codes)
    m = np.zeros((n, n))
    windows = [interference_windows(c, codes[0].length, fractions=fractions, kind=kind) for c in codes]
    for i, a in enumerate(codes):
        for j in range(n):
            if i == j:
                m[i, i] = float(periodic_correlation(a, a, kind)[1:].max(initial=-1.0))
            else:
                m[i, j] = float(correlation(a, windows[j], kind).max(initial=0.0))
    return m


#: Steps of `_clique`'s backtracking search at most (per threshold of `family`).
CLIQUE_STEPS = 200_000


def _clique(adj: np.ndarray, size: int, order: np.ndarray) -> tuple[list[int] | None, bool]:
    """(a clique of ``size`` vertices in a boolean adjacency matrix or None, whether the search
    stopped at `CLIQUE_STEPS` first: then None does not mean there is none)."""
    best: list[int] | None = None
    budget = [CLIQUE_STEPS]

    def grow(chosen: list[int], cand: list[int]) -> bool:
        nonlocal best
        budget[0] -= 1
        if len(chosen) == size:
            best = list(chosen)
            return True
        if len(chosen) + len(cand) < size or budget[0] <= 0:
            return False
        for idx, v in enumerate(cand):
            rest = [u for u in cand[idx + 1:] if adj[v, u]]
            if grow(chosen + [v], rest):
                return True
        return False

    grow([], [int(v) for v in order])
    return best, best is None and budget[0] <= 0


@functools.lru_cache(maxsize=64)
def family(n_devices: int, length: int, kind: str = "frame") -> tuple[SourceCode, ...]:
    """N codes of length L for N unsynchronised devices sharing a room.

    Exhaustive over primitive necklaces (one rotation per class: two rotations of one string would
    correlate perfectly at some phase), then the smallest threshold tau for which N codes exist whose
    pairwise `worst_interference` (both directions, every on/off order, integer and half-slot offsets;
    ties broken by the integer-offset worst case) is <= tau.  Ties prefer balanced codes (weight L/2) and lower autocorrelation sidelobes.  L <= `MAX_SEARCH_LENGTH`.
    The search for N such codes at a threshold takes at most `CLIQUE_STEPS` steps; where it stops
    there first, the next threshold is tried and a RuntimeWarning says the family may not be the
    best one.
    """
    if n_devices < 1:
        raise ValueError(f"n_devices must be >= 1, got {n_devices}")
    if not 2 <= length <= MAX_SEARCH_LENGTH:
        raise ValueError(f"family search supports 2 <= L <= {MAX_SEARCH_LENGTH}, got L={length}")
    if kind not in ("frame", "event"):
        raise ValueError(f"kind must be 'frame' or 'event', got {kind!r}")
    cands = necklaces(length)
    if len(cands) < n_devices:
        raise ValueError(f"only {len(cands)} distinct primitive codes of length {length}; asked for {n_devices}")
    m = worst_interference_matrix(cands, kind, fractions=2)  # integer and half-slot offsets
    m_int = worst_interference_matrix(cands, kind, fractions=1)
    m = m + 1e-3 * m_int  # among equal half-slot worst cases prefer the better integer-offset one
    pair = np.maximum(m, m.T)
    np.fill_diagonal(pair, -np.inf)
    balance = np.array([abs(c.weight - length / 2) for c in cands])
    side = np.diag(m)
    order = np.lexsort((side, balance))
    if n_devices == 1:
        return (SourceCode(cands[int(order[0])].bits, f"family-1x{length}-0"),)
    levels = np.unique(pair[np.isfinite(pair)])
    chosen = None
    cut_short: list[float] = []
    for tau in levels:
        adj = pair <= tau + 1e-9
        chosen, stopped = _clique(adj, n_devices, order)
        if chosen is not None:
            break
        if stopped:
            cut_short.append(float(tau))
    if chosen is None:
        stop = f" (the search stopped after {CLIQUE_STEPS} steps at {len(cut_short)} thresholds)" if cut_short else ""
        raise ValueError(f"no family of {n_devices} codes of length {length} found{stop}")
    if cut_short:
        warnings.warn(f"family({n_devices}, {length}): the code search stopped after {CLIQUE_STEPS} steps at "
                      f"threshold {cut_short[0]:.3f}; the family found (threshold {float(tau):.3f}) may not have "
                      f"the smallest worst interference", RuntimeWarning, stacklevel=2)
    return tuple(SourceCode(cands[i].bits, f"family-{n_devices}x{length}-{r}") for r, i in enumerate(chosen))


def correlation_report(codes: Iterable[SourceCode], kind: str = "frame") -> str:
    """Text report: each code's periodic autocorrelation (all L cyclic shifts), each pair's periodic
    cross-correlation (all shifts, equal lengths only) and worst unsynchronised interference."""
    codes = list(codes)
    lines = [f"kind={kind}  (frame: Pearson vs zero-mean template; event: cosine vs transitions)"]
    for c in codes:
        ac = periodic_correlation(c, c, kind)
        lines.append(f"  auto  {c.string:>12}  shifts 0..{c.length - 1}: " + " ".join(f"{v:+.2f}" for v in ac))
    for a in codes:
        for b in codes:
            if a is b:
                continue
            worst = worst_interference(a, b, kind=kind)
            per = (" ".join(f"{v:+.2f}" for v in periodic_correlation(a, b, kind))
                   if a.length == b.length else "(lengths differ)")
            lines.append(f"  cross {a.string:>12} <- {b.string:<12} periodic: {per}   worst unsync: {worst:+.3f}")
    return "\n".join(lines)


# --------------------------------------------------------------------------------------------
# Spreading
# --------------------------------------------------------------------------------------------

def spread(frames: np.ndarray, code: SourceCode, *, off: str = "dark") -> np.ndarray:
    """Spread a projection sequence over the code's slots.

    frames: (m,) or (m, ...) on/off values (bool or 0/1 integers; any value > 0 counts as "on",
    intensities in between are scaled: a frame value v becomes ``v * bits`` so grey patterns spread
    too).  Returns (m * L, ...) with the input dtype: slot ``i * L + j`` is ``frames[i] * bits[j]``,
    and with ``off="complement"`` the "off" part of every pixel sends ``(max - frames[i]) * (1 - bits[j])``
    on top, where max is 1 for bool/float inputs and the dtype maximum for integer inputs.
    """
    f = np.asarray(frames)
    if f.ndim == 0 or f.shape[0] == 0:
        raise ValueError(f"frames must be (m, ...) with m >= 1, got shape {f.shape}")
    if off not in OFF_MODES:
        raise ValueError(f"off must be one of {OFF_MODES}, got {off!r}")
    bits = code.bits.reshape((1, code.length) + (1,) * (f.ndim - 1))
    fx = f[:, None]
    if f.dtype == bool:
        on = fx & bits.astype(bool)
        if off == "complement":
            on = on | (~fx & ~bits.astype(bool))
        return on.reshape((-1,) + f.shape[1:])
    top = np.iinfo(f.dtype).max if np.issubdtype(f.dtype, np.integer) else 1.0
    out = fx * bits.astype(f.dtype)
    if off == "complement":
        out = out + (top - fx) * (1 - bits).astype(f.dtype)
    return out.astype(f.dtype).reshape((-1,) + f.shape[1:])
