"""What a per-pixel decoder can reach: the coding gain of `decode()`'s defaults against the
Bayes rule that knows everything about the scene except each pixel's own levels.

    python tools/eval_per_pixel_limit.py [--size 160x120] [--seeds 0 1] [--ambient 0.5 1 2]
                                         [--atoms 512] [--top 64]
                                         [--out docs/results/per_pixel_limit/README.md]

The captures are `tools/eval_posterior.py`'s (edge.sim's flying scene and the tests'
plane-box-sphere renderer, 12-bit, every frame at T / n, ambient = 0.5 / 1 / 2 x projector), gray-10
and ecc-22-10.  The error rate is the same: lit pixels whose column is wrong or that are not
published, P(wrong) < `MAX_ERROR` publishing.  Five decoders per code:

* **decode()**: the library's defaults (the product).
* **its model, every codeword**: `decode()`'s own cost of each codebook row (`posterior._word_cost`:
  the row's least-squares levels, the noise model and level prior the decode fitted to the
  capture) summed over all rows instead of the top three and the sampled low-weight tail, with
  the decode's own P(not lit) (and without its goodness-of-fit test, `edge.decode.misfit`).
  Where this equals the first column, the search and the tail cost nothing and the gap to the
  columns below is the model's.
* **scene-law Bayes rule**: the posterior of the best-informed per-pixel decoder.  It knows the
  camera's true noise, the share of lit pixels, and the scene's distribution of true (on, off)
  levels (lit pixels) and of flat levels (unlit pixels), each as `--atoms` pixels drawn from the
  scene; not the pixel's own levels.  Per pixel, P(lit, row c | x) ∝ share_lit / rows * mean over
  the lit atoms of N(x; levels of c) and P(unlit | x) ∝ (1 - share_lit) * mean over the unlit atoms
  of N(x; flat level), exactly (rows: the `--top` best rows by `decode()`'s model, the column before;
  the rest add nothing at these margins).  The published column is the most probable row, P(wrong)
  the mass (unlit included) more than one row from it.  The column before it is the same rule
  with the noise model `decode()` fitted to the capture instead of the camera's: what the
  level law alone is worth.
* **true levels, lit known**: `eval_posterior.bound_error`, which also knows each pixel's levels
  and that it is lit: no decoder has this.

The gain is gray-10's error rate over ecc-22-10's.  The scene-law rule is the reference a
per-pixel decoder is measured against, not a strict bound on this error rate: publishing at a
fixed P(wrong) target is not what a posterior optimises, and a decoder whose P(wrong) is less
sharp can publish a few more right pixels (plane-box-sphere at ambient 2).  Where its gain is
below a target, a decoder that treats pixels one by one can at best come close to it on that
scene; spatial methods (neighbours' columns or levels) are the way past it.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from numba import njit, prange

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tools"))
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT))

import eval_posterior as ev  # noqa: E402
import edge.decode.decoder as decoder  # noqa: E402
import edge.decode.posterior as posterior  # noqa: E402
from edge.codes import get_code  # noqa: E402
from edge.commands._args import parse_size  # noqa: E402
from edge.decode import decode  # noqa: E402
from edge.decode.level_prior import kernel_args  # noqa: E402

CODES = ("gray-10", "ecc-22-10")
#: The default target of `decode()` (`DecodeSettings.max_error`).
MAX_ERROR = 0.01
COLUMNS = ("decode()", "its model, every codeword", "scene-law rule, decode()'s noise fit", "scene-law Bayes rule",
           "true levels, lit known")


@njit(cache=True, inline="always")
def _pixel_sums(S, p):
    """(sum, sum of squares) of pixel p's samples S[p]."""
    tot = 0.0
    sq = 0.0
    for i in range(S.shape[1]):
        tot += S[p, i]
        sq += S[p, i] * S[p, i]
    return tot, sq


@njit(cache=True, inline="always")
def _row_sums(S, X, p, c):
    """(count, sum, sum of squares) of pixel p's samples where row c's symbol X[c] is 1."""
    n1 = 0.0
    s1 = 0.0
    q1 = 0.0
    for i in range(S.shape[1]):
        if X[c, i] != 0.0:
            n1 += 1.0
            s1 += S[p, i]
            q1 += S[p, i] * S[p, i]
    return n1, s1, q1


@njit(cache=True, inline="always")
def _neg2_log_mean_exp(costs, count):
    """-2 log mean_k exp(-costs[k] / 2) over the first ``count`` costs (shifted by their least)."""
    least = np.inf
    for k in range(count):
        least = min(least, costs[k])
    acc = 0.0
    for k in range(count):
        acc += np.exp(-0.5 * (costs[k] - least))
    return least - 2.0 * np.log(acc / count)


@njit(cache=True, parallel=True)
def model_costs(S, X, a, beta, ptab, pu0, pdu, pw0, pdw, pout, use_prior, out):
    """out (P, rows) = `posterior._word_cost` of every row for every pixel: S (P, m) samples, X
    (rows, m) symbols, (a, beta) the noise model, the rest `level_prior.kernel_args`."""
    npix, m = S.shape
    for p in prange(npix):
        tot, sq = _pixel_sums(S, p)
        for c in range(X.shape[0]):
            n1, s1, q1 = _row_sums(S, X, p, c)
            out[p, c] = posterior._word_cost(m, n1, tot, s1, sq, q1, a, beta, ptab, pu0, pdu, pw0, pdw, pout,
                                             use_prior)


@njit(cache=True, parallel=True)
def marginal_costs(S, X, rows, on, off, flat, a, beta, out_lit, out_unlit):
    """The scene-law Bayes rule's likelihoods, -2 log (up to the constant m log 2 pi):
    out_lit (P, T)[p, t] = -2 log mean_k N(S[p]; row rows[p, t]'s levels (on[k], off[k])) and
    out_unlit (P,)[p] = -2 log mean_j N(S[p]; every sample at flat[j]), with N a product of normals
    of variance a + beta * level.  S (P, m), X (rows, m) symbols 0 / 1, rows (P, T) int64, on / off
    (K,), flat (J,) float64 levels (normalised)."""
    npix, m = S.shape
    K = on.size
    J = flat.size
    lv1 = np.log(a + beta * on)
    lv0 = np.log(a + beta * off)
    r1 = 1.0 / (a + beta * on)
    r0 = 1.0 / (a + beta * off)
    lvf = np.log(a + beta * flat)
    rf = 1.0 / (a + beta * flat)
    for p in prange(npix):
        tot, sq = _pixel_sums(S, p)
        ck = np.empty(max(K, J))
        for t in range(rows.shape[1]):
            n1, s1, q1 = _row_sums(S, X, p, rows[p, t])
            n0 = m - n1
            s0 = tot - s1
            q0 = sq - q1
            for k in range(K):
                h = on[k]
                o = off[k]
                ck[k] = ((q1 - 2.0 * h * s1 + n1 * h * h) * r1[k] + n1 * lv1[k]
                         + (q0 - 2.0 * o * s0 + n0 * o * o) * r0[k] + n0 * lv0[k])
            out_lit[p, t] = _neg2_log_mean_exp(ck, K)
        for j in range(J):
            f = flat[j]
            ck[j] = (sq - 2.0 * f * tot + m * f * f) * rf[j] + m * lvf[j]
        out_unlit[p] = _neg2_log_mean_exp(ck, J)


def published_errors(cost: np.ndarray, rows: np.ndarray, truth_rows: np.ndarray, p_other: np.ndarray,
                     other_cost: np.ndarray | None = None) -> int:
    """Lit pixels counted as errors by the Bayes rule over ``cost`` (P, T) -2 log posterior of
    the rows ``rows`` (P, T): the most probable row is published where P(wrong) < MAX_ERROR, P(wrong)
    the mass more than one row from it; with ``other_cost`` (P,) an unlit hypothesis in the same
    sum, else ``p_other`` (P,) an independent P(not lit) combined as `posterior._combine` does."""
    least = cost.min(1, keepdims=True)
    if other_cost is not None:
        least = np.minimum(least, other_cost[:, None])
    odds = np.exp(-0.5 * (cost - least))
    at = cost.argmin(1)
    best = np.take_along_axis(rows, at[:, None], 1)[:, 0]
    near = (odds * (np.abs(rows - best[:, None]) <= 1)).sum(1)
    total = odds.sum(1)
    if other_cost is not None:
        total = total + np.exp(-0.5 * (other_cost - least[:, 0]))
        p_wrong = 1.0 - near / total
    else:
        p_wrong = 1.0 - (1.0 - p_other) * (near / total)
    return int(((p_wrong >= MAX_ERROR) | (best != truth_rows)).sum())


def decode_with_model(f: np.ndarray, w: np.ndarray, b: np.ndarray, bits: int, code) -> tuple:
    """(Decoded, noise, fdr, idx): `decode()` with its defaults on frames ``f`` (n, H, W), white
    ``w`` and black ``b`` (H, W) at ``bits``, and what its error rule's posterior used: the noise
    model with the level prior, and its P(not lit) lookup (`posterior._not_lit_lookup`: fdr (nb +
    1,) float64, idx (H, W) int64)."""
    seen = {}
    original, lookup = decoder.posterior, posterior._not_lit_lookup

    def spy(*args, **kwargs):
        seen["noise"] = args[6]
        return original(*args, **kwargs)

    def spy_lookup(*args, **kwargs):
        seen["not_lit"] = lookup(*args, **kwargs)
        return seen["not_lit"]

    decoder.posterior, posterior._not_lit_lookup = spy, spy_lookup
    try:
        d = decode(f, w, b, code, bit_depth=bits)
    finally:
        decoder.posterior, posterior._not_lit_lookup = original, lookup
    return d, seen["noise"], *seen["not_lit"]


def error_counts(gen, levels_of, code, ratio: float, seed: int, size: tuple[int, int], atoms: int,
                 top: int) -> np.ndarray:
    """(6,) int64: lit pixels, then the errors of the five `COLUMNS` on one capture."""
    f, w, b, bits, col, lit = gen(code, ratio, seed, size)
    d, noise, fdr, idx = decode_with_model(f, w, b, bits, code)
    S = ev.samples_of(f, w, b, bits, lit)
    X = ev.symbols(code)
    truth_rows = col[lit].astype(np.int64)
    every = np.broadcast_to(np.arange(code.size, dtype=np.int64), (S.shape[0], code.size))
    # the decode's own model over every row, with its own P(not lit)
    own = np.empty((S.shape[0], code.size))
    model_costs(S, X, float(noise.a), float(noise.beta), *kernel_args(noise.levels)[:7], own)
    k = idx[lit]
    p_not_lit = np.where(k >= 0, fdr[np.maximum(k, 0)], 1.0)
    # the scene-law Bayes rule: the scene's level distributions, the lit share, the true noise
    on, off = levels_of(code, ratio, seed, size)
    a, beta = ev.SIM_NOISE
    rng = np.random.default_rng([seed, 11])
    lit_at = rng.choice(int(lit.sum()), size=min(atoms, int(lit.sum())), replace=False)
    unlit_levels = off[~lit]
    flat = (unlit_levels[rng.choice(unlit_levels.size, size=min(atoms, unlit_levels.size), replace=False)]
            if unlit_levels.size else np.zeros(1))
    rows = np.ascontiguousarray(np.argsort(own, 1, kind="stable")[:, :top])
    share = lit.mean()
    scene_law = []
    for noise_model in ((float(noise.a), float(noise.beta)), (a, beta)):  # the decode's fit, the camera's
        lit_cost = np.empty(rows.shape)
        unlit_cost = np.empty(S.shape[0])
        marginal_costs(S, X, rows, np.ascontiguousarray(on[lit][lit_at]), np.ascontiguousarray(off[lit][lit_at]),
                       np.ascontiguousarray(flat, np.float64), *noise_model, lit_cost, unlit_cost)
        lit_cost += 2.0 * np.log(code.size / share)
        unlit_cost = (unlit_cost - 2.0 * np.log(1.0 - share)) if share < 1.0 else np.full(S.shape[0], np.inf)
        scene_law.append(published_errors(lit_cost, rows, truth_rows, np.zeros(S.shape[0]), unlit_cost))
    bound, _ = ev.bound_error(f, w, b, bits, on, off, code, col, lit, (a, beta), max_error=MAX_ERROR)
    return np.array([int(lit.sum()),
                     int((((d.column != col) | ~d.valid) & lit).sum()),
                     published_errors(own, every, truth_rows, p_not_lit),
                     *scene_law,
                     int(round(bound * lit.sum()))], np.int64)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", default="160x120", help="scene size WxH (default 160x120)")
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1], help="scene / noise seeds (default 0 1)")
    ap.add_argument("--ambient", type=float, nargs="+", default=list(ev.RATIOS),
                    help="ambient light as a multiple of the projector's (default %(default)s)")
    ap.add_argument("--atoms", type=int, default=512,
                    help="scene pixels standing for each level distribution of the scene-law rule (default 512)")
    ap.add_argument("--top", type=int, default=64,
                    help="rows per pixel the scene-law rule sums over, the best by decode()'s model (default 64)")
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "results" / "per_pixel_limit" / "README.md",
                    help="markdown file the table is also written to (default docs/results/per_pixel_limit/README.md)")
    args = ap.parse_args(argv)
    size = parse_size(args.size)
    if args.atoms < 1 or not 1 <= args.top <= 1024:
        raise ValueError(f"--atoms must be >= 1 and --top within 1..1024 (the codes' rows), got {args.atoms} and "
                         f"{args.top}")
    if not all(r > 0 for r in args.ambient):
        raise ValueError(f"--ambient must be > 0, got {args.ambient}")
    lines: list[str] = []

    def say(text: str) -> None:
        print(text, flush=True)
        lines.append(text)

    say(f"Command: `python tools/eval_per_pixel_limit.py --size {args.size} --seeds {' '.join(map(str, args.seeds))} "
        f"--ambient {' '.join(f'{r:g}' for r in args.ambient)} --atoms {args.atoms} --top {args.top}`\n")
    say(f"Error rate (wrong or unpublished, over lit pixels), P(wrong) < {MAX_ERROR}; each cell gray-10 / "
        f"ecc-22-10 (gain)\n")
    say("| scene, ambient | " + " | ".join(COLUMNS) + " |")
    say("|---" * (len(COLUMNS) + 1) + "|")
    for gen_name, gen, levels_of in (("edge.sim", ev.sim_capture, ev.sim_levels),
                                     ("plane-box-sphere", ev.pbs_capture, ev.pbs_levels)):
        for ratio in args.ambient:
            rates = {}
            for name in CODES:
                code = get_code(name)
                total = sum(error_counts(gen, levels_of, code, ratio, seed, size, args.atoms, args.top)
                            for seed in args.seeds)
                rates[name] = total[1:] / max(int(total[0]), 1)
            cells = [f"{g:.2%} / {e:.2%} ({g / max(e, 1e-9):.2f}x)" for g, e in zip(rates[CODES[0]], rates[CODES[1]])]
            say(f"| {gen_name}, {ratio:g} | " + " | ".join(cells) + " |")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text("# What a per-pixel decoder can reach\n\n" + __doc__.split("\n\n", 2)[2].strip()
                            + "\n\n" + "\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    from edge.cli import tool_main

    raise SystemExit(tool_main(main, __file__))
