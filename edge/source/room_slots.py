"""Slot-level room simulation: N unsynchronised devices' light on P pixels of one device's camera.

Device 0 (mine) projects a stack of m symbols (m - 2 random on/off pattern symbols, then white and
black, like a DLP column stack), each spread over my L-slot code.  Every other device k sends its
own random on/off symbols spread with its code, on its own clock: offset tau_k (uniform over
[0, 1000) slots, fractional) and slot-rate drift ``1 + d_k`` (uniform within +-``drift``), so its
symbol boundaries fall anywhere in my slots and move across the stack; the foreign stream is
integrated over my slots at 1/16 slot.  Powers: my own level A per pixel uniform in [0.2, 1];
device k's level at a pixel uniform in [0, ``power_ratio``] x A ("each foreign device at most as
bright as the own one" for ratio 1), present on ``coverage`` of the pixels; ambient uniform in
[0, 0.5]; Gaussian noise ``sigma`` per slot.  80 % of my pixels are lit by my own device.

Detectors compared (`evaluate`), each deciding per pixel and pattern symbol "own light on":

* ``joint``: `edge.source.joint` (all other members' codes known, offsets estimated, threshold
  from the measured noise);
* ``matched``: the plain matched filter (`despread`, correlation >= 0.85, amplitude >= 0.1) and half
  the pixel's white amplitude;
* ``uncoded``: every device sends plain on/off (L = 1); "on" when the symbol's intensity minus the
  black symbol exceeds half the white minus black;
* ``time-division``: N synchronised slots, mine alone in my slot: the single-device result at
  frame rate / N.

Metrics: ``own_kept`` = detected own "on" symbols / own "on" symbols (lit pixels), ``false`` =
detected "on" among own "off" symbols and unlit pixels.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..codes.source import SourceCode
from .joint import detect, joint_despread
from .matched_filter import despread


@dataclass(frozen=True)
class SlotScenario:
    n_devices: int
    length: int = 8
    symbols: int = 24
    pixels: int = 3000
    power_ratio: float = 1.0
    coverage: float = 0.7
    drift: float = 1e-3
    sigma: float = 0.02
    seed: int = 0


def _stream(code_bits: np.ndarray, symbols_on: np.ndarray, n_slots: int, offset: float, drift: float,
            sub: int = 16) -> np.ndarray:
    """(n_slots, P) foreign light integrated over my slots: its symbol s covers its slots s*L..s*L+L-1."""
    L = code_bits.size
    tt = (np.arange(n_slots * sub) + 0.5) / sub
    u = (tt - offset) * (1.0 + drift)
    sym = np.floor(u / L).astype(np.int64)
    chip = np.floor(u).astype(np.int64) % L
    on = code_bits[chip] == 1
    s0 = sym.min()
    vals = symbols_on[(sym - s0) % symbols_on.shape[0]]  # (n_slots*sub, P)
    light = vals * on[:, None]
    return light.reshape(n_slots, sub, -1).mean(axis=1)


def simulate(sc: SlotScenario, codes: list[SourceCode] | None):
    """(slots (m*L, 1, P) float32, own_on (m-2, P) bool truth).  codes None = uncoded (L = 1)."""
    rng = np.random.default_rng([sc.seed, sc.n_devices])
    L = 1 if codes is None else codes[0].length
    m, P = sc.symbols, sc.pixels
    n = m * L
    own_bits = np.ones(1, np.uint8) if codes is None else codes[0].bits
    A = rng.uniform(0.2, 1.0, P)
    lit = rng.random(P) < 0.8
    sym = rng.integers(0, 2, (m, P))
    sym[-2], sym[-1] = 1, 0
    r = np.zeros((n, P))
    for i in range(m):
        r[i * L:(i + 1) * L] += (A * sym[i] * lit)[None] * own_bits[:, None]
    r += rng.uniform(0, 0.5, P)[None]
    for k in range(1, sc.n_devices):
        bits = np.ones(1, np.uint8) if codes is None else codes[k].bits
        level = A * rng.uniform(0, sc.power_ratio, P) * (rng.random(P) < sc.coverage)
        n_sym = n // bits.size + 4
        on = rng.integers(0, 2, (n_sym, P)) * level[None]
        r += _stream(bits, on, n, rng.uniform(0, 1000), rng.uniform(-sc.drift, sc.drift))
    r += sc.sigma * rng.standard_normal(r.shape)
    truth = (sym[:-2] == 1) & lit[None]
    return r.reshape(n, 1, P).astype(np.float32), truth


def _rates(det: np.ndarray, truth: np.ndarray) -> dict:
    return {"own_kept": float(det[truth].mean()) if truth.any() else float("nan"),
            "false": float(det[~truth].mean()) if (~truth).any() else float("nan")}


def evaluate(sc: SlotScenario, family: tuple[SourceCode, ...]) -> dict[str, dict]:
    """Rates of the detectors (module docstring) for ``sc``; ``family`` has >= N codes of length L."""
    codes = list(family[: sc.n_devices])
    slots, truth = simulate(sc, codes)
    own, foreign = codes[0], codes[1:]
    out: dict[str, dict] = {}
    jr = joint_despread(slots, own, foreign)
    out["joint"] = _rates(detect(jr, jr.amplitude[-2])[:-2, 0], truth)
    ds = despread(slots, own, threshold=0.85, min_amplitude=0.1)
    ref = ds.frames[-2, 0]
    out["matched"] = _rates(ds.accepted[:-2, 0] & (ds.frames[:-2, 0] > 0.5 * np.maximum(ref, 1e-6)[None]), truth)
    uslots, utruth = simulate(sc, None)
    u = uslots[:, 0]
    white, black = u[-2], u[-1]
    udet = ((u[:-2] - black[None]) > 0.5 * (white - black)[None]) & ((white - black) > 0.1)[None]
    out["uncoded"] = _rates(udet, utruth)
    single = SlotScenario(1, sc.length, sc.symbols, sc.pixels, sc.power_ratio, sc.coverage, sc.drift, sc.sigma, sc.seed)
    s1, t1 = simulate(single, codes[:1])
    j1 = joint_despread(s1, own, [])
    out["time-division"] = _rates(detect(j1, j1.amplitude[-2])[:-2, 0], t1)
    return out
