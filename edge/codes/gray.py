"""Uncoded patterns: binary, reflected Gray and Gupta et al.'s XOR-02 / XOR-04 codes.

All of them use every k-bit string once (d_min = 1); they differ in which column sends which
string.  They are written as linear codes (identity-like generators) so every decoder treats them
like any other code.
"""

from __future__ import annotations

import numpy as np

from .code import Code, gray
from .gf2 import encode


def binary_code(k: int = 10) -> Code:
    """Plain binary counter: column j sends the k bits of j, MSB first (frame 0 = coarsest)."""
    _check_k(k)
    g = np.eye(k, dtype=np.uint8)
    messages = np.arange(2**k, dtype=np.int64)
    return Code(
        name=f"binary-{k}", family="binary", codebook=encode(messages, g), k=k, systematic=True,
        generator=g, messages=messages, construction="column index in binary, MSB first",
        order="binary", promised_d_min=1,
    )


def gray_code(k: int = 10) -> Code:
    """Reflected binary Gray code: column j sends gray(j) = j ^ (j >> 1), MSB first."""
    _check_k(k)
    g = np.eye(k, dtype=np.uint8)
    messages = gray(np.arange(2**k, dtype=np.int64))
    return Code(
        name=f"gray-{k}", family="gray", codebook=encode(messages, g), k=k, systematic=True,
        generator=g, messages=messages, construction="reflected binary Gray code, MSB first",
        order="gray", promised_d_min=1,
    )


def xor_code(k: int = 10, base_stripe: int = 2) -> Code:
    """Gupta et al. (ICCV 2011) XOR-02 / XOR-04 codes.

    Start from the k-bit Gray code; the base plane is the Gray bit plane whose stripes are
    ``base_stripe`` projector columns wide (2 -> the finest plane, frame k-1; 4 -> frame k-2).
    Every coarser plane is XOR-ed with the base plane, so every projected frame is high-frequency;
    the base plane and any finer plane are sent unchanged.  Decoding XORs the base back, which the
    generator matrix below expresses: frame i = gray bit i XOR gray bit base.
    """
    _check_k(k)
    if base_stripe not in (2, 4):
        raise ValueError(f"XOR code base stripe width must be 2 or 4, got {base_stripe}")
    base = k - 1 if base_stripe == 2 else k - 2
    if base < 1:
        raise ValueError(f"XOR-{base_stripe:02d} needs k >= {k - base + 1}, got k={k}")
    g = np.eye(k, dtype=np.uint8)
    g[base, :base] = 1
    messages = gray(np.arange(2**k, dtype=np.int64))
    return Code(
        name=f"xor{base_stripe:02d}-{k}", family=f"xor{base_stripe:02d}", codebook=encode(messages, g), k=k,
        systematic=False, generator=g, messages=messages,
        construction=f"Gray code, planes 0..{base - 1} XOR-ed with the stripe-width-{base_stripe} plane {base}",
        order="gray", promised_d_min=1,
    )


def _check_k(k: int) -> None:
    if not isinstance(k, (int, np.integer)) or not 1 <= k <= 16:
        raise ValueError(f"uncoded patterns need 1 <= k <= 16 bits, got k={k!r}")
