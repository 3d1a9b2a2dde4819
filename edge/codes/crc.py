"""CRC-appended codes (error detection) and the search for CRC polynomials that keep frames
high-frequency (paper section 4, appendix E "Unfavorable codes in EDC").

Polynomial convention
---------------------
A CRC of width ``w`` (3..8) has a generator polynomial of degree exactly ``w`` with constant term
1.  It may be given either

* without the leading ``x**w`` term (the usual "normal" notation: CRC-5-ITU is ``0x15`` =
  x^5 + x^4 + x^2 + 1, USB is ``0x05`` = x^5 + x^2 + 1, EPC is ``0x09`` = x^5 + x^3 + 1), i.e.
  ``poly < 2**w``; or
* with it (``0x35`` for CRC-5-ITU), i.e. ``2**w <= poly < 2**(w+1)``.

Anything else (degree above ``w``, even constant term) is a ValueError.

The CRC is computed over the *projected bits* of the base code (frame 0 = highest power), with zero
initial value and no final XOR, so it is linear: the appended code has generator
``[G_base | G_base @ P]`` (P: `parity_matrix`) and keeps the base's messages and column order.  It
is systematic when the base is.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .code import Code, encode_messages
from .gfq import poly2_mod

CRC_WIDTHS = range(3, 9)

#: Default polynomial (without the leading term) for ``<base>+crc<w>`` names.
DEFAULT_POLY = {
    3: 0x3,   # CRC-3-GSM    x^3 + x + 1
    4: 0x3,   # CRC-4-ITU    x^4 + x + 1
    5: 0x15,  # CRC-5-ITU    x^5 + x^4 + x^2 + 1 (reaches d_min 4 on 10 data bits)
    6: 0x03,  # CRC-6-ITU    x^6 + x + 1
    7: 0x09,  # CRC-7        x^7 + x^3 + 1
    8: 0x07,  # CRC-8-CCITT  x^8 + x^2 + x + 1
}

#: Well-known CRC-5 polynomials (without the leading term).
CRC5_ITU, CRC5_USB, CRC5_EPC = 0x15, 0x05, 0x09


def full_polynomial(poly: int, width: int) -> int:
    """The generator polynomial with its ``x**width`` term set, after validating degree and width."""
    if not isinstance(width, (int, np.integer)) or width not in CRC_WIDTHS:
        raise ValueError(f"CRC width must be 3..8, got {width!r}")
    if not isinstance(poly, (int, np.integer)) or poly < 0:
        raise ValueError(f"CRC polynomial must be a non-negative integer, got {poly!r}")
    poly = int(poly)
    if poly >> width == 0:
        full = poly | (1 << width)
    elif poly >> width == 1:
        full = poly
    else:
        raise ValueError(
            f"CRC-{width} polynomial 0x{poly:x} has degree {poly.bit_length() - 1}; expected degree {width} "
            f"(0x{1 << width:x}..0x{(2 << width) - 1:x} with the x^{width} term, or below 0x{1 << width:x} without it)"
        )
    if not full & 1:
        raise ValueError(f"CRC-{width} polynomial 0x{poly:x} must have constant term 1 (odd value)")
    return full


def polynomial_text(full: int) -> str:
    """``x^5+x^4+x^2+1`` for 0x35."""
    terms = [("1" if d == 0 else "x" if d == 1 else f"x^{d}") for d in range(full.bit_length() - 1, -1, -1)
             if (full >> d) & 1]
    return "+".join(terms)


def parity_matrix(n_data: int, poly: int, width: int) -> np.ndarray:
    """(n_data, width) uint8: CRC bits (MSB = coefficient of x**(width-1) first) of each unit data
    word; bit i of the data is the coefficient of x**(n_data-1-i)."""
    full = full_polynomial(poly, width)
    out = np.zeros((n_data, width), dtype=np.uint8)
    for i in range(n_data):
        rem = poly2_mod(1 << (n_data - 1 - i + width), full)
        out[i] = [(rem >> (width - 1 - b)) & 1 for b in range(width)]
    return out


def crc_bits(data: np.ndarray, poly: int, width: int) -> np.ndarray:
    """CRC of binary rows: (M, n_data) uint8 -> (M, width) uint8."""
    data = np.asarray(data, dtype=np.int64)
    if data.ndim != 2:
        raise ValueError(f"CRC data must be (M, n_data) binary rows, got shape {data.shape}")
    return ((data @ parity_matrix(data.shape[1], poly, width)) & 1).astype(np.uint8)


def crc_passes(words: np.ndarray, poly: int, width: int) -> np.ndarray:
    """(M, n) received binary words -> (M,) bool, True where the last ``width`` bits equal the CRC
    of the others (False = error detected)."""
    words = np.asarray(words, dtype=np.uint8)
    if words.ndim != 2 or words.shape[1] <= width:
        raise ValueError(f"CRC-{width} check needs (M, n) words with n > {width} bits, got shape {words.shape}")
    return np.all(crc_bits(words[:, :-width], poly, width) == words[:, -width:], axis=1)


def crc_code(base: Code, poly: int, width: int, *, name: str | None = None) -> Code:
    """``base`` with a CRC of ``width`` bits appended to every codeword (d_min computed exactly)."""
    if base.q != 2:
        raise ValueError(f"CRCs are appended to binary codes; {base.name!r} has q={base.q}")
    full = full_polynomial(poly, width)
    p = parity_matrix(base.n, poly, width)
    label = f"CRC-{width} 0x{full & ((1 << width) - 1):0{(width + 3) // 4}x} ({polynomial_text(full)})"
    common = dict(
        name=name or f"{base.name}+crc{width}-0x{full & ((1 << width) - 1):x}", family="crc", k=base.k,
        construction=f"{base.name} ({base.construction}) + {label} over its {base.n} frames",
        order=base.order,
    )
    if base.is_linear:
        g = np.concatenate([base.generator, (base.generator.astype(np.int64) @ p & 1).astype(np.uint8)], axis=1)
        return Code(codebook=encode_messages(base.messages, g), systematic=base.systematic, generator=g,
                    messages=base.messages, **common)
    cb = np.concatenate([base.codebook, crc_bits(base.codebook, poly, width)], axis=1)
    return Code(codebook=cb, systematic=False, **common)


# --- EDC polynomial search -------------------------------------------------------------------

def longest_runs(codebook: np.ndarray) -> np.ndarray:
    """(n,) int: widest stripe of every frame, in codebook columns (longest run of equal symbols
    over consecutive projector columns)."""
    cb = np.asarray(codebook)
    m, n = cb.shape
    out = np.zeros(n, dtype=np.int64)
    for f in range(n):
        change = np.flatnonzero(cb[1:, f] != cb[:-1, f]) + 1
        edges = np.concatenate([[0], change, [m]])
        out[f] = int(np.diff(edges).max())
    return out


@dataclass(frozen=True)
class EdcRecord:
    """One CRC polynomial appended to one base code.

    max_stripe: widest stripe (columns) among the appended CRC frames; min_transitions: fewest 0-1
    transitions among them; high_frequency: max_stripe <= bound (`edc_search`); d_min: of the
    whole appended code.
    """

    base: str
    width: int
    poly: int
    poly_full: int
    n: int
    d_min: int
    max_stripe: int
    min_transitions: int
    high_frequency: bool

    @property
    def polynomial(self) -> str:
        return polynomial_text(self.poly_full)


#: Default high-frequency bound of `edc_search`: widest stripe, in codebook columns, that still counts
#: as high-frequency.  4 is the base stripe of Gupta et al.'s XOR-04 code, the coarsest of their
#: high-frequency codes.
HIGH_FREQUENCY_STRIPE = 4


def edc_search(base: Code, widths: range | list[int] = range(3, 7), *,
               max_stripe: int = HIGH_FREQUENCY_STRIPE) -> list[EdcRecord]:
    """Every CRC polynomial (degree w, constant term 1) of each width, appended to ``base``.

    High-frequency criterion (measurable): an appended CRC frame is high-frequency when its widest
    stripe (longest run of equal bits over consecutive codebook columns, `longest_runs`) is at most
    ``max_stripe`` columns (default `HIGH_FREQUENCY_STRIPE` = 4, XOR-04's stripe).  A combination
    is favourable when all its appended frames are.  With ``stripe > 1`` in `render` every width
    scales by the stripe.  Records are sorted best first: high-frequency, larger d_min, fewer
    frames, narrower stripes, more transitions.
    """
    widths = list(widths)
    for w in widths:
        if w not in CRC_WIDTHS:
            raise ValueError(f"CRC widths must lie in 3..8, got {w}")
    bound = int(max_stripe)
    if bound < 1:
        raise ValueError(f"max_stripe must be >= 1 column, got {max_stripe}")
    records = []
    for w in widths:
        for low in range(1, 1 << w, 2):
            code = crc_code(base, low, w, name=f"{base.name}+crc{w}-0x{low:x}")
            extra = code.codebook[:, base.n:]
            runs = longest_runs(extra)
            transitions = (extra[1:] != extra[:-1]).sum(axis=0)
            records.append(EdcRecord(
                base=base.name, width=w, poly=low, poly_full=low | (1 << w), n=code.n, d_min=code.d_min,
                max_stripe=int(runs.max()), min_transitions=int(transitions.min()),
                high_frequency=bool(runs.max() <= bound),
            ))
    records.sort(key=lambda r: (not r.high_frequency, -r.d_min, r.width, r.max_stripe, -r.min_transitions, r.poly))
    return records
