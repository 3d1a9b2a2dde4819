"""Source-code families for N devices in one room, with a guarantee on the SUM of N-1 foreign devices.

Model (one matched-filter window of L slots at one pixel, frame sensors)::

    r = A * bits_own + c * 1 + sum_k p_k * w_k + noise

A >= 0 is the own light (0 where the own device does not light the pixel or sends an "off"), c the
constant ambient, w_k the window foreign device k puts on my slots (its code, its on/off symbol
states, its clock offset tau_k, at unit power) and p_k >= 0 its power relative to my own "on"
level A_ref at that pixel.  The matched filter's linear response is the *normalised amplitude*

    a = <s, r> / <s, s>          s = bits_own - weight / L   (zero mean: c cancels; own light gives A)

**Fractional offsets reduce to integer ones (proof).**  My slot j integrates the foreign stream over
my time [j, j+1).  The foreign stream is piecewise constant on [tau + m, tau + m + 1); with
tau = n + f (n integer, 0 <= f < 1) slot j receives ``f * x[j-n-1] + (1-f) * x[j-n]``, so the window
at tau is the convex combination ``(1-f) * w(n) + f * w(n+1)`` of the windows at the two adjacent
integer offsets *for the same symbol stream*, and so is its response <s, w>.  Hence the supremum
(infimum) of the response over all fractional offsets and symbol streams is attained at an integer
cyclic shift, and `response_bounds` computes it exactly from the integer-offset windows
(`edge.codes.source.interference_windows` with ``fractions=1``).  Event sensors (signed edge counts
per slot, template = the code's transitions): an edge at time tau + m falls in slot
``floor(tau + m - guard)``, which is constant while tau moves between two slot boundaries, so every
fractional window *equals* one of the integer-offset windows.  Both statements need equal slot
durations; clock drift (ppm) moves the offset by far less than a slot within one window and is
covered by "arbitrary offset".  `tests/test_source_room.py` checks both against 1/16-slot offsets.

**Sum over devices is exact.**  With beta_plus[i, j] = max(0, sup response of code i to code j) and
beta_minus[i, j] = max(0, -inf ...), and every foreign device at most P times as bright as the own
one, the offsets, streams and powers of the N-1 devices are independent, so

    no own light:  a <= P * sum_j beta_plus[i, j]           (false detection bound)
    own "on":      a >= A * (1 - P * sum_j beta_minus[i, j]) (own-signal bound, relative to A)

and both bounds are *attained* (each device at its own worst offset, full power): they are the
exact worst cases, not just bounds.  A per-device threshold theta_i (fraction of A_ref) between
them separates own light from any foreign sum iff the **guaranteed margin**

    margin_i(P) = 1 - P * sum_j (beta_plus[i, j] + beta_minus[i, j]) > 0,

and the largest per-device power ratio with a guarantee is ``P* = 1 / max_i sum_j (...)``.  With
noise, detection is error-free while the amplitude noise (sigma / |s| per slot noise sigma) stays
below margin_i * A / 2 on each side of theta_i = (P sum beta_plus + 1 - P sum beta_minus) / 2.

Comparisons: **no coding** (L = 1, intensity threshold): every foreign device adds up to P with no
negative part, margin 1 - (N-1) P, P* = 1 / (N-1); **time-division** (N synchronised slots, what
RealSense / Azure Kinect do with a hardware sync cable): margin 1 at any P, frame rate / N and a
sync wire; **source codes**: frame rate / L, no wiring.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from .source import SourceCode, interference_windows, necklaces, source_code

#: Code lengths the exhaustive necklace search covers (longer codes use balanced necklaces only).
EXHAUSTIVE_MAX_LENGTH = 12
#: Longest code length `room_family` accepts.
MAX_ROOM_LENGTH = 16


STREAMS = ("aperiodic", "periodic")


def foreign_windows(foreign: SourceCode, length: int, *, kind: str = "frame", stream: str = "aperiodic") -> np.ndarray:
    """The integer-offset windows (K, length) a foreign device puts on a window of ``length`` slots.

    stream ``"aperiodic"``: the device sends its code for "on" symbols and dark slots for "off"
    symbols in any order (DLP patterns, light-curtain steps); ``"periodic"``: it repeats its code
    without pause (dot projectors, event-camera dots): only its cyclic shifts (same length only).
    """
    if stream == "aperiodic":
        return interference_windows(foreign, length, fractions=1, kind=kind)
    if stream != "periodic":
        raise ValueError(f"stream must be one of {STREAMS}, got {stream!r}")
    if foreign.length != length:
        raise ValueError(f"periodic windows need equal lengths, got {foreign.length} and {length}")
    rolled = np.stack([np.roll(foreign.bits, -k) for k in range(length)]).astype(np.float64)
    if kind == "event":
        rolled = rolled - np.roll(rolled, 1, axis=1)
    return rolled


def response_bounds(mine: SourceCode, foreign: SourceCode, *, kind: str = "frame",
                    stream: str = "aperiodic") -> tuple[float, float]:
    """Exact (sup, inf) of the normalised linear response ``<s, w> / <s, s>`` of ``mine``'s matched
    filter to every window an unsynchronised ``foreign`` device can put on it (any on/off symbol
    order, any fractional offset; see the module docstring: integer offsets attain both).

    kind ``"frame"``: s = zero-mean template, w = slot intensities; ``"event"``: s = transitions,
    w = signed edge counts.  Unit foreign power (its "on" level equals my own "on" level).
    """
    s = _template(mine, kind)
    w = foreign_windows(foreign, mine.length, kind=kind, stream=stream)
    if w.size == 0:
        return 0.0, 0.0
    r = (w @ s) / float(s @ s)
    return float(r.max()), float(r.min())


def _template(code: SourceCode, kind: str) -> np.ndarray:
    if kind == "frame":
        return code.template
    if kind == "event":
        return code.transitions.astype(np.float64)
    raise ValueError(f"kind must be 'frame' or 'event', got {kind!r}")


def bound_matrices(codes: Sequence[SourceCode], *, kind: str = "frame",
                   stream: str = "aperiodic") -> tuple[np.ndarray, np.ndarray]:
    """(beta_plus, beta_minus), each float64 (N, N): entry [i, j] = max(0, sup) and max(0, -inf) of
    code i's response to code j (`response_bounds`); diagonal 0 (a device is synchronised with itself)."""
    codes = list(codes)
    n = len(codes)
    if n == 0:
        return np.zeros((0, 0)), np.zeros((0, 0))
    length = codes[0].length
    if any(c.length != length for c in codes):
        raise ValueError(f"a room family needs one code length, got {[c.length for c in codes]}")
    windows = [foreign_windows(c, length, kind=kind, stream=stream) for c in codes]
    bp, bm = np.zeros((n, n)), np.zeros((n, n))
    for i, a in enumerate(codes):
        s = _template(a, kind)
        s2 = float(s @ s)
        for j in range(n):
            if i == j or windows[j].size == 0:
                continue
            r = (windows[j] @ s) / s2
            bp[i, j] = max(0.0, float(r.max()))
            bm[i, j] = max(0.0, float(-r.min()))
    return bp, bm


@dataclass(frozen=True)
class Guarantee:
    """Worst case of a family under the SUM of the other N-1 devices (see the module docstring).

    codes: the family; power_ratio: P (each foreign device at most P x the own "on" level);
    false_bound: float64 (N,) largest response with no own light, P * sum_j beta_plus[i, j];
    own_bound: float64 (N,) smallest response to own light A = 1, 1 - P * sum_j beta_minus[i, j];
    threshold: float64 (N,) per-device threshold (fraction of the own level) halfway between;
    margin: float64 (N,) own_bound - false_bound; max_power_ratio: P* = largest P with margin > 0
    for every device (inf for N = 1).
    """

    codes: tuple[SourceCode, ...]
    kind: str
    stream: str
    power_ratio: float
    false_bound: np.ndarray
    own_bound: np.ndarray
    threshold: np.ndarray
    margin: np.ndarray
    max_power_ratio: float

    @property
    def guaranteed_margin(self) -> float:
        """min_i margin_i: > 0 means every device separates own light from any foreign sum."""
        return float(self.margin.min()) if self.margin.size else 1.0


def guarantee(codes: Sequence[SourceCode], *, power_ratio: float = 1.0, kind: str = "frame",
              stream: str = "aperiodic") -> Guarantee:
    """The exact worst case of ``codes`` sharing a room (each foreign device <= ``power_ratio`` x own)."""
    codes = tuple(source_code(c) for c in codes)
    if not power_ratio >= 0:
        raise ValueError(f"power_ratio must be >= 0, got {power_ratio}")
    bp, bm = bound_matrices(codes, kind=kind, stream=stream)
    sp, sm = bp.sum(axis=1), bm.sum(axis=1)
    false_b = power_ratio * sp
    own_b = 1.0 - power_ratio * sm
    cost = float((sp + sm).max(initial=0.0))
    return Guarantee(codes, kind, stream, float(power_ratio), false_b, own_b, (false_b + own_b) / 2, own_b - false_b,
                     float("inf") if cost <= 0 else 1.0 / cost)


@functools.lru_cache(maxsize=16)
def _candidates(length: int, kind: str, stream: str) -> tuple[tuple[SourceCode, ...], np.ndarray]:
    """Candidate codes of ``length`` and their (K, K) cost matrix beta_plus + beta_minus."""
    cands = necklaces(length)
    if length > EXHAUSTIVE_MAX_LENGTH:
        cands = [c for c in cands if abs(c.weight - length / 2) <= 0.5]
    if kind == "event":
        cands = [c for c in cands if np.count_nonzero(c.transitions) >= 2]
    bp, bm = bound_matrices(cands, kind=kind, stream=stream)
    return tuple(cands), bp + bm


def _objective(cost: np.ndarray, members: list[int]) -> float:
    sub = cost[np.ix_(members, members)]
    return float(sub.sum(axis=1).max(initial=0.0))


@functools.lru_cache(maxsize=256)
def room_family(n_devices: int, length: int, kind: str = "frame", stream: str = "aperiodic") -> tuple[SourceCode, ...]:
    """N codes of length L minimising the worst SUM interference max_i sum_j (beta_plus + beta_minus).

    Search: all primitive necklaces of length L (balanced ones for L > 12), greedy growth from the
    best balanced code, then swap improvement until no single swap lowers the objective
    (deterministic; a local optimum, its guarantee is exact for the codes it returns: `guarantee`).
    Raises ValueError when fewer than N codes of length L exist.
    """
    if n_devices < 1:
        raise ValueError(f"n_devices must be >= 1, got {n_devices}")
    if not 2 <= length <= MAX_ROOM_LENGTH:
        raise ValueError(f"room families support 2 <= L <= {MAX_ROOM_LENGTH}, got L={length}")
    cands, cost = _candidates(length, kind, stream)
    k = len(cands)
    if k < n_devices:
        raise ValueError(f"only {k} usable codes of length {length} ({kind}); asked for {n_devices} devices")
    balance = np.array([abs(c.weight - length / 2) for c in cands])
    order = [int(i) for i in np.lexsort((cost.sum(axis=1), balance))]
    members = [order[0]]
    while len(members) < n_devices:
        best, best_v = None, np.inf
        for c in order:
            if c in members:
                continue
            v = _objective(cost, members + [c])
            if v < best_v - 1e-12:
                best, best_v = c, v
        members.append(best)
    current = _objective(cost, members)
    for _ in range(50):
        improved = False
        for pos in range(len(members)):
            for c in order:
                if c in members:
                    continue
                trial = members[:pos] + [c] + members[pos + 1:]
                v = _objective(cost, trial)
                if v < current - 1e-12:
                    members, current, improved = trial, v, True
        if not improved:
            break
    tag = "" if stream == "aperiodic" else "p"
    return tuple(SourceCode(cands[i].bits, f"room{tag}-{n_devices}x{length}-{r}") for r, i in enumerate(members))


@dataclass(frozen=True)
class TableRow:
    """One (N, L) entry of `margin_table`: the family, its margin at ``power_ratio``, P*, frame-rate cost."""

    n_devices: int
    length: int
    scheme: str            # "source codes" | "no coding" | "time-division"
    margin: float          # guaranteed margin at the table's power ratio (fraction of own level)
    max_power_ratio: float
    frame_cost: int        # camera frames per projected frame (frame rate divides by this)
    codes: tuple[str, ...] = ()
    needs_sync: bool = False


def uncoded_row(n_devices: int, power_ratio: float = 1.0) -> TableRow:
    """No coding: every foreign device adds up to P to the intensity, nothing cancels."""
    others = n_devices - 1
    return TableRow(n_devices, 1, "no coding", 1.0 - power_ratio * others,
                    float("inf") if others == 0 else 1.0 / others, 1)


def tdm_row(n_devices: int) -> TableRow:
    """Time-division multiplexing: device k lights slot k of N (hardware-synchronised)."""
    return TableRow(n_devices, n_devices, "time-division", 1.0, float("inf"), n_devices, needs_sync=True)


def margin_table(ns: Sequence[int] = tuple(range(2, 17)), lengths: Sequence[int] = (4, 6, 8, 10, 12, 14, 16), *,
                 power_ratio: float = 1.0, kind: str = "frame", stream: str = "aperiodic") -> list[TableRow]:
    """The N x L table of guaranteed margins of `room_family` (exact worst case of the sum), with
    the no-coding and time-division rows for each N.  Entries with fewer than N codes are skipped."""
    rows: list[TableRow] = []
    for n in ns:
        rows.append(uncoded_row(n, power_ratio))
        rows.append(tdm_row(n))
        for length in lengths:
            try:
                fam = room_family(n, length, kind, stream)
            except ValueError:
                continue
            g = guarantee(fam, power_ratio=power_ratio, kind=kind, stream=stream)
            rows.append(TableRow(n, length, "source codes", g.guaranteed_margin, g.max_power_ratio, length,
                                 tuple(c.string for c in fam)))
    return rows


def format_table(rows: Sequence[TableRow], *, power_ratio: float = 1.0) -> str:
    """Markdown: one line per N; per L the margin at P (and P* in brackets), plus no coding and TDM."""
    lengths = sorted({r.length for r in rows if r.scheme == "source codes"})
    ns = sorted({r.n_devices for r in rows})
    head = ["N", "no coding (cost 1)", "time-division (cost N, sync)"] + [f"L={L} (cost {L})" for L in lengths]
    out = [f"guaranteed margin at power ratio P = {power_ratio:g} (fraction of the own level; > 0 = "
           "guaranteed separation), [largest P with a guarantee]", "",
           "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    fmt = lambda r: f"{r.margin:+.3f} [{'inf' if np.isinf(r.max_power_ratio) else f'{r.max_power_ratio:.2f}'}]"  # noqa: E731
    for n in ns:
        by = {(r.scheme, r.length): r for r in rows if r.n_devices == n}
        cells = [str(n), fmt(by[("no coding", 1)]), fmt(by[("time-division", n)])]
        cells += [fmt(by[("source codes", L)]) if ("source codes", L) in by else "-" for L in lengths]
        out.append("| " + " | ".join(cells) + " |")
    return "\n".join(out)


# -- a profile's room family (duck-typed: reads profile.sensor / projector / room / name) --------

def room_code_kind(profile) -> tuple[str, str]:
    """(kind, stream) of a profile's family: ``event`` for event sensors (else ``frame``); ``periodic``
    for dot projectors (they repeat their code), ``aperiodic`` for DLP patterns and light curtains."""
    kind = "event" if profile.sensor.backend == "event" else "frame"
    stream = "periodic" if profile.projector.kind == "dots" else "aperiodic"
    return kind, stream


def room_family_for(profile):
    """The room's source-code family for ``profile`` (`edge.codes.source_room.room_family` with
    ``[room] family_size`` codes of ``[room] code_length`` slots)."""
    kind, stream = room_code_kind(profile)
    try:
        return room_family(profile.room.family_size, profile.room.code_length, kind, stream)
    except ValueError as exc:
        raise ValueError(f"profile {profile.name!r}: [room] family_size = {profile.room.family_size}, "
                         f"code_length = {profile.room.code_length}: {exc}") from None
