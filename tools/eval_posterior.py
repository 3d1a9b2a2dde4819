"""The "error" validity rule with `decode`'s defaults: coding gain, spatial methods, calibration.

    python tools/eval_posterior.py [--size 160x120] [--seeds 0 1] [--out docs/results/posterior]

Two scene generators (`edge.sim`'s flying scene, 12-bit, sigma_s 0.04; the tests' independent
plane / box / sphere renderer, 12-bit), fixed total exposure (every frame at T / n), ambient 0.5 /
1 / 2 x the projector.  Prints the error rate (wrong or invalid, over lit pixels) of gray-10 and
ecc-15/22/31/63-10 decoded with the defaults, and the ratio to gray-10; the same for ecc-22-10
with the spatial methods (list, median, sgm); where gray-10's and ecc-22-10's errors are (published
with a wrong column, or unpublished with the top-1 column right, one row off or further off);
the noise model each decode fitted; the bound a decoder that knew each pixel's true levels
would reach (`bound_error`: the same metric and target, the Bayes rule with the true on / off
levels and the camera's noise, for gray-10 and the ECC codes; beside it the same rule with
each codeword's own least-squares levels and no level prior); and the reliability table of P(wrong)
(predicted vs observed rate of columns more than one row off, per bin, each bin's error count judged against "within 2x" with
its 99 % Poisson interval, `edge.eval.report.calibration_verdict`) on both generators, and on the real OpenCV capture
(../shared/data/procam-graycode, where present) the coverage and 7x7-median outlier rate of
`validity="error"` with and without its inverse frames (its 7x7-median outliers of the top-1
columns as the observed errors of the reliability table).  Writes README.md and
reliability.png to --out.  Apart from that one ``validity`` on the real capture (whose inverse
frames `validity="auto"` gives the confidence rule), no option of `decode` is set.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT))

sys.path.insert(0, str(ROOT / "tools"))

from _plane_box_sphere import render, scene as pbs_scene  # noqa: E402
from edge.codes import get_code  # noqa: E402
from edge.commands._args import parse_size  # noqa: E402
from edge.decode import decode  # noqa: E402
from edge.eval.report import calibration_verdict  # noqa: E402
from edge.sim import CameraModel, capture_code  # noqa: E402
from edge.sim.metrics import truth  # noqa: E402
from edge.sim.scenes import make_scene  # noqa: E402
from real_data import REAL_CAPTURE  # noqa: E402

CODES = ("gray-10", "ecc-15-10", "ecc-22-10", "ecc-31-10", "ecc-63-10")
RATIOS = (0.5, 1.0, 2.0)
SPATIAL = ("list", "median", "sgm")
BINS = (0.0005, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5)


#: edge.sim's camera noise in `sim_capture`: (sigma_r, sigma_s); its variance is sigma_r**2 + sigma_s**2 * I.
SIM_SIGMAS = (0.002, 0.04)


def sim_camera(ratio):
    """`sim_capture`'s camera: 12-bit, `SIM_SIGMAS`, ambient = ratio x projector (sum 0.8)."""
    a = 0.8 * ratio / (1 + ratio)
    return CameraModel(bits=12, sigma_r=SIM_SIGMAS[0], sigma_s=SIM_SIGMAS[1], ambient=a, projector=0.8 - a)


def sim_capture(code, ratio, seed, size):
    scene = make_scene("flying", size[0], size[1], seed=seed)
    cap = capture_code(scene, code, sim_camera(ratio), rng=np.random.default_rng([seed, 7]))
    col, lit = truth(scene)
    return cap.frames, cap.white, cap.black, 12, col, lit


def sim_levels(code, ratio, seed, size):
    """The true (on, off) levels (H, W) of `sim_capture`'s pixels, normalised: its white / black
    frames rendered without noise at 16 bits."""
    scene = make_scene("flying", size[0], size[1], seed=seed)
    cap = capture_code(scene, code, sim_camera(ratio).with_(bits=16, sigma_r=0.0, sigma_s=0.0), rng=0)
    return cap.white / 65535.0, cap.black / 65535.0


def samples_of(frames: np.ndarray, white: np.ndarray, black: np.ndarray, bits: int, where: np.ndarray) -> np.ndarray:
    """(P, n + 2) float64 normalised samples (code frames, white, black) of the pixels ``where``
    ((H, W) bool), in raster order."""
    r = np.concatenate([frames, white[None], black[None]]).astype(np.float64) / float(2 ** bits - 1)
    return np.ascontiguousarray(r.reshape(r.shape[0], -1).T[where.ravel()])


def symbols(code) -> np.ndarray:
    """(rows, n + 2) float64 0 / 1: every codebook row's symbols, then white (1) and black (0)."""
    return np.ascontiguousarray(np.concatenate([code.codebook.astype(np.float64), np.ones((code.size, 1)),
                                                np.zeros((code.size, 1))], 1))


def bound_costs(samples, on, off, code, noise):
    """(true, own): (P, N) float64 costs (-2 log-likelihood up to a per-pixel constant) of every
    codebook row of a binary code for P pixels.  samples: (P, n + 2) normalised, the n code
    samples then white and black; on / off: (P,) the pixels' true levels; noise: (a, beta) of the
    variance ``a + beta * I``.  "true": ``sum_i (r_i - mu_i)**2 / v(mu_i) + log v(mu_i)`` with
    mu_i the true on / off level of the row's symbol; "own": the row's own least-squares on / off
    levels (the mean of its samples at 1 and at 0; where that puts on below off, one mean of all
    samples) under the true variances."""
    a, beta = noise
    r = np.asarray(samples, np.float64)
    m = r.shape[1]
    x = symbols(code)
    hi, lo = np.asarray(on, np.float64)[:, None], np.asarray(off, np.float64)[:, None]
    v1, v0 = a + beta * hi, a + beta * lo
    true = ((r - hi) ** 2 / v1 + np.log(v1) - (r - lo) ** 2 / v0 - np.log(v0)) @ x.T
    n1 = x.sum(1)
    s1, q1 = r @ x.T, (r * r) @ x.T
    st, qt = r.sum(1, keepdims=True), (r * r).sum(1, keepdims=True)
    own = (q1 - s1 * s1 / n1) / v1 + (qt - q1 - (st - s1) ** 2 / (m - n1)) / v0
    pooled = (qt - st * st / m) / v0
    return true, np.where(s1 / n1 < (st - s1) / (m - n1), pooled, own)


def bound_error(frames, white, black, bits, on, off, code, col, lit, noise, max_error=0.01):
    """(error rate with the true levels, error rate with each row's own levels), wrong or
    unpublished over the lit pixels, of the Bayes rule of a binary code on `bound_costs`: a
    uniform prior over the codebook rows, P(wrong) = the posterior mass more than one row from
    the best, published where below max_error.  frames (n, H, W), white / black (H, W) raw at
    ``bits``; on / off (H, W) true levels, normalised; col (H, W) true rows; lit (H, W) bool;
    noise (a, beta).  On lit pixels only (the bound's question is the column, not "lit?")."""
    samples = samples_of(frames, white, black, bits, lit)
    rows = np.arange(code.size)
    truth_col = col[lit]

    def rate(cost):
        best = cost.argmin(1)
        odds = np.exp(-(cost - cost.min(1, keepdims=True)) / 2)
        near = np.abs(rows[None, :] - best[:, None]) <= 1
        p_wrong = 1.0 - (odds * near).sum(1) / odds.sum(1)
        return float(((p_wrong >= max_error) | (best != truth_col)).mean())

    true, own = bound_costs(samples, on[lit], off[lit], code, noise)
    return rate(true), rate(own)


def pbs_capture(code, ratio, seed, size, **noise):
    """The plane-box-sphere capture (12-bit); ``noise``: `render`'s read / shot / bits overrides."""
    col, albedo = pbs_scene(size[0], size[1], seed=seed + 3)
    f, w, b = render(code.codebook, col, albedo, ambient=0.12 * ratio, projector=0.12, seed=seed + 4,
                     **{"bits": 12, **noise})
    return f, w, b, 12, col, np.ones(col.shape, bool)


def pbs_levels(code, ratio, seed, size):
    """The true (on, off) levels of `pbs_capture`'s pixels: its white / black rendered without
    noise, as floats."""
    _, on, off, *_ = pbs_capture(code, ratio, seed, size, read=0.0, shot=0.0, bits=None)
    return on.astype(np.float64), off.astype(np.float64)


#: The codes `bound_error` is computed for (binary), and both generators' camera noise (a, beta):
#: edge.sim's `SIM_SIGMAS`, the plane-box-sphere renderer's defaults (read 0.002, shot 0.04).
BOUND = ("gray-10", "ecc-22-10", "ecc-63-10")
SIM_NOISE = (SIM_SIGMAS[0] ** 2, SIM_SIGMAS[1] ** 2)

#: The codes whose errors `error_kinds` splits up.
COMPOSITION = ("gray-10", "ecc-22-10")


def error_kinds(column: np.ndarray, valid: np.ndarray, top: np.ndarray, truth_col: np.ndarray,
                lit: np.ndarray) -> np.ndarray:
    """(4,) int64 counts of the lit pixels that count as errors: published with a column other
    than the true one; unpublished with the best candidate (top, (H, W) int) equal to the true
    column, one row off, further off (or none).  Their sum is the error rate's numerator."""
    off = ~valid & lit
    dist = np.abs(top.astype(np.int64) - truth_col)
    return np.array([int((valid & (column != truth_col) & lit).sum()), int((off & (dist == 0)).sum()),
                     int((off & (dist == 1)).sum()), int((off & ((dist > 1) | (top < 0))).sum())], np.int64)


#: The real capture beside the repository (`tools/real_data.py`).
REAL = REAL_CAPTURE


def reliability(p: np.ndarray, o: np.ndarray) -> list[tuple[float, float, float, int]]:
    """(lo, predicted mean, observed rate, pixels) per BINS bin with >= 30 pixels."""
    out = []
    for lo, hi in zip(BINS[:-1], BINS[1:]):
        s = (p >= lo) & (p < hi)
        if s.sum() >= 30:
            out.append((lo, float(p[s].mean()), float(o[s].mean()), int(s.sum())))
    return out


def bin_cells(rel: list[tuple[float, float, float, int]]) -> str:
    """One reliability line: per bin ``[lo) predicted / observed (pixels), errors seen for
    expected: verdict`` (`edge.eval.report.calibration_verdict`, within 2x at 99 %)."""
    cells = []
    for lo, p, o, k in rel:
        expected, seen = p * k, int(round(o * k))
        cells.append(f"[{lo:g}) {p:.4f} / {o:.4f} ({k}), {seen} for {expected:.1f}: {calibration_verdict(expected, seen)}")
    return " | ".join(cells)


def calibration_summary(rels: list[list[tuple[float, float, float, int]]]) -> str:
    """How many bins from 0.05 % to 20 % (`BINS`) are within 2x of their expected error count,
    how many only consistent with it at 99 %, and how many off (`bin_cells`)."""
    verdicts = [calibration_verdict(p * k, int(round(o * k)))
                for rel in rels for lo, p, o, k in rel if lo < 0.2]
    return (f"{len(verdicts)} bins from 0.05 % to 20 %: {verdicts.count('within')} within 2x, "
            f"{verdicts.count('consistent')} consistent with 2x at 99 % on their error count, "
            f"{verdicts.count('off')} off")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", default="160x120", help="scene size WxH (default 160x120)")
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1], help="scene / noise seeds (default 0 1)")
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "results" / "posterior",
                    help="folder for README.md and reliability.png (default docs/results/posterior)")
    ap.add_argument("--real", type=Path, default=REAL, help="OpenCV Gray-code capture folder, skipped if absent "
                    "(default ../shared/data/procam-graycode/capture_0)")
    args = ap.parse_args(argv)
    size = parse_size(args.size)
    lines: list[str] = [f"Command: `python tools/eval_posterior.py --size {args.size} --seeds "
                        f"{' '.join(map(str, args.seeds))}`", ""]

    def say(text: str = "") -> None:
        print(text, flush=True)
        lines.append(text)

    curves: dict[str, dict[str, list]] = {}
    for gen_name, gen in (("edge.sim", sim_capture), ("plane-box-sphere", pbs_capture)):
        pred, obs = {c: [] for c in CODES}, {c: [] for c in CODES}
        parts: list[str] = []
        fits: list[str] = []
        say(f"\n## {gen_name}: error rate with defaults (wrong or invalid), ratio to gray-10\n")
        say("| ambient | " + " | ".join(CODES) + " | " + " | ".join(f"ecc-22-10 {m}" for m in SPATIAL) + " |")
        say("|---" * (len(CODES) + len(SPATIAL) + 1) + "|")
        bounds: list[str] = []
        levels_of = sim_levels if gen is sim_capture else pbs_levels
        for ratio in RATIOS:
            err = {}
            kinds = {c: np.zeros(4, np.int64) for c in COMPOSITION}
            bound = {c: np.zeros(2) for c in BOUND}
            noise = {c: [] for c in CODES}
            for name in CODES + SPATIAL:
                code = get_code(name if name in CODES else "ecc-22-10")
                method = "soft" if name in CODES else name
                e_sum = n_sum = 0
                for seed in args.seeds:
                    f, w, b, bd, col, lit = gen(code, ratio, seed, size)
                    d = decode(f, w, b, code, bit_depth=bd, method=method)
                    e_sum += int((((d.column != col) | ~d.valid) & lit).sum())
                    n_sum += int(lit.sum())
                    if name in COMPOSITION:
                        kinds[name] += error_kinds(d.column, d.valid, d.candidates[..., 0], col, lit)
                    if name in BOUND:
                        on, off = levels_of(code, ratio, seed, size)
                        bound[name] += np.array(bound_error(f, w, b, bd, on, off, code, col, lit, SIM_NOISE)) * lit.sum()
                    if name in CODES:
                        noise[name].append((d.stats["noise_a"], d.stats["noise_beta"]))
                        pred[name].append(d.error[lit])
                        obs[name].append((np.abs(d.candidates[..., 0] - col) > 1)[lit])
                err[name] = e_sum / n_sum
            g = err["gray-10"]
            cells = [f"{err[c]:.4f}" + ("" if c == "gray-10" else f" ({g / max(err[c], 1e-9):.1f}x)") for c in CODES]
            cells += [f"{err[m]:.4f} ({err['ecc-22-10'] / max(err[m], 1e-9):.1f}x soft)" for m in SPATIAL]
            say(f"| {ratio} | " + " | ".join(cells) + " |")
            lit_total = n_sum
            fits.append(f"| {ratio} | " + " | ".join(
                f"{min(v[0] for v in noise[c]):.1e}-{max(v[0] for v in noise[c]):.1e} / "
                f"{min(v[1] for v in noise[c]):.2e}-{max(v[1] for v in noise[c]):.2e}" for c in CODES) + " |")
            parts += [f"| {ratio} | {c} | {err[c]:.4f} | " + " | ".join(f"{k / lit_total:.4f}" for k in kinds[c]) + " |"
                      for c in COMPOSITION]
            bounds.append(f"| {ratio} | " + " | ".join(
                f"{err[c]:.4f} / {bound[c][0] / lit_total:.4f} / {bound[c][1] / lit_total:.4f}" for c in BOUND)
                + " | " + " | ".join(f"{err['gray-10'] / max(err[c], 1e-9):.2f}x / "
                                     f"{bound['gray-10'][0] / max(bound[c][0], 1e-9):.2f}x / "
                                     f"{bound['gray-10'][1] / max(bound[c][1], 1e-9):.2f}x" for c in BOUND[1:]) + " |")
        say(f"\n{gen_name}: where the errors are (shares of the lit pixels; unpublished = P(wrong) >= "
            "max_error)\n")
        say("| ambient | code | error rate | published, wrong | unpublished, top-1 right | "
            "unpublished, top-1 one row off | unpublished, top-1 further off |")
        say("|---|---|---|---|---|---|---|")
        for row in parts:
            say(row)
        say(f"\n{gen_name}: what knowing the levels is worth (error rate: decode() / the Bayes rule with each "
            "pixel's true levels and the camera's noise / the same rule with each codeword's own levels and no "
            "level prior; then the gain over gray-10 of each)\n")
        say("| ambient | " + " | ".join(BOUND) + " | " + " | ".join(f"{c} gain" for c in BOUND[1:]) + " |")
        say("|---" * (2 * len(BOUND)) + "|")
        for row in bounds:
            say(row)
        say(f"\n{gen_name}: the fitted noise model, variance a + beta * I (a / beta, least-most over the seeds)"
            + (f"; the camera's: {SIM_SIGMAS[0] ** 2:.1e} / {SIM_SIGMAS[1] ** 2:.2e}" if gen is sim_capture else "") + "\n")
        say("| ambient | " + " | ".join(CODES) + " |")
        say("|---" * (len(CODES) + 1) + "|")
        for row in fits:
            say(row)
        say(f"\n{gen_name}: P(wrong) predicted / observed (column more than one row off), per bin "
            "(pixels), then the bin's errors seen for the count its predictions expect, and the verdict on "
            "'within 2x' (within; consistent at 99 % on the count; off), all ambient levels\n")
        curves[gen_name] = {}
        for name in CODES:
            rel = reliability(np.concatenate(pred[name]), np.concatenate(obs[name]))
            curves[gen_name][name] = rel
            say(f"- {name}: " + bin_cells(rel))
        say(f"\n{gen_name}: {calibration_summary(list(curves[gen_name].values()))}")
    if args.real.is_dir():
        from edge.decode import load_opencv_graycode, spatial_outliers

        cap = load_opencv_graycode(args.real, (1024, 768))
        say("\n## Real OpenCV Gray-code capture (validity='error'; OpenCV: 56 % at 0.01 %)\n")
        say("| frames | coverage | x OpenCV | 7x7 outliers |")
        say("|---|---|---|---|")
        for label, inv in (("pattern + inverse", cap.inverse), ("pattern only", None)):
            d = decode(cap.frames, cap.white, cap.black, cap.code, columns=cap.columns, inverse=inv, validity="error")
            e = spatial_outliers(d.column, d.valid, window=7, tol=2)
            say(f"| {label} | {d.valid.mean():.4f} | {d.valid.mean() / 0.56:.3f} | "
                f"{e.sum() / max(d.valid.sum(), 1):.6f} ({int(e.sum())}) |")
            if inv is not None:
                top = d.candidates[..., 0]
                o = spatial_outliers(top, top >= 0, window=7, tol=2)
                curves["real (pattern + inverse)"] = {"gray-10": reliability(d.error.ravel(), o.ravel())}
        rel = curves["real (pattern + inverse)"]["gray-10"]
        say("\nreal: P(wrong) predicted / 7x7-median outlier rate of the top-1 columns, per bin\n")
        say("- gray-10: " + bin_cells(rel))
        say(f"\nreal: {calibration_summary([rel])} (an outlier of the 7x7 median is not every error: "
            "a miss its neighbours share is not one)")
    args.out.mkdir(parents=True, exist_ok=True)
    _plot(curves, args.out / "reliability.png")
    (args.out / "README.md").write_text("# The error-probability rule with decode()'s defaults\n\n"
                                        + "\n".join(lines) + "\n\n![reliability](reliability.png)\n")
    print(f"wrote {args.out / 'README.md'} and reliability.png")
    return 0


def _plot(curves: dict[str, dict[str, list]], path: Path) -> None:
    """Reliability plot: predicted P(wrong) vs observed rate per bin, one panel per data set."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(curves), figsize=(4.2 * len(curves), 4.0), squeeze=False)
    for ax, (title, per_code) in zip(axes[0], curves.items()):
        lim = (5e-4, 0.6)
        ax.fill_between(lim, [lim[0] / 2, lim[1] / 2], [lim[0] * 2, lim[1] * 2], color="0.9", label="within 2x")
        ax.plot(lim, lim, "k--", lw=0.8)
        for name, rel in per_code.items():
            if rel:
                ax.plot([r[1] for r in rel], [max(r[2], 1e-4) for r in rel], "o-", ms=3, label=name)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlim(*lim)
        ax.set_ylim(1e-4, 1.0)
        ax.set_xlabel("predicted P(wrong)")
        ax.set_ylabel("observed rate")
        ax.set_title(title, fontsize=9)
        ax.legend(fontsize=6)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    from edge.cli import tool_main

    raise SystemExit(tool_main(main, __file__))
