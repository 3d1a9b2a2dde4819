"""The "error" validity rule with `decode`'s defaults: coding gain, spatial methods, calibration.

    python tools/eval_posterior.py [--size 160x120] [--seeds 0 1]

Two scene generators (`edge.sim`'s flying scene, 12-bit, sigma_s 0.04; the tests' independent
plane / box / sphere renderer, 12-bit), fixed total exposure (every frame at T / n), ambient 0.5 /
1 / 2 x the projector.  Prints the error rate (wrong or invalid, over lit pixels) of gray-10 and
ecc-15/22/31/63-10 decoded with the defaults, and the ratio to gray-10; the same for ecc-22-10
with the spatial methods (list, median, sgm); and the reliability table of P(wrong) (predicted vs observed rate of
columns more than one row off, per bin) on edge.sim.  No option of `decode` is set.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT))

from _plane_box_sphere import render, scene as pbs_scene  # noqa: E402
from edge.codes import get_code  # noqa: E402
from edge.decode import decode  # noqa: E402
from edge.sim import CameraModel, capture_code  # noqa: E402
from edge.sim.metrics import truth  # noqa: E402
from edge.sim.scenes import make_scene  # noqa: E402

CODES = ("gray-10", "ecc-15-10", "ecc-22-10", "ecc-31-10", "ecc-63-10")
RATIOS = (0.5, 1.0, 2.0)
SPATIAL = ("list", "median", "sgm")
BINS = (0.0005, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5)


def sim_capture(code, ratio, seed, size):
    scene = make_scene("flying", size[0], size[1], seed=seed)
    a = 0.8 * ratio / (1 + ratio)
    cam = CameraModel(bits=12, sigma_r=0.002, sigma_s=0.04, ambient=a, projector=0.8 - a)
    cap = capture_code(scene, code, cam, rng=np.random.default_rng([seed, 7]))
    col, lit = truth(scene)
    return cap.frames, cap.white, cap.black, 12, col, lit


def pbs_capture(code, ratio, seed, size):
    col, albedo = pbs_scene(size[0], size[1], seed=seed + 3)
    f, w, b = render(code.codebook, col, albedo, ambient=0.12 * ratio, projector=0.12, bits=12, seed=seed + 4)
    return f, w, b, 12, col, np.ones(col.shape, bool)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", default="160x120", help="scene size WxH (default 160x120)")
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1], help="scene / noise seeds (default 0 1)")
    args = ap.parse_args(argv)
    size = tuple(int(v) for v in args.size.split("x"))
    pred, obs = {c: [] for c in CODES}, {c: [] for c in CODES}
    for gen_name, gen in (("edge.sim", sim_capture), ("plane-box-sphere", pbs_capture)):
        print(f"\n## {gen_name}: error rate with defaults (wrong or invalid), ratio to gray-10")
        print("| ambient | " + " | ".join(CODES) + " | " + " | ".join(f"ecc-22-10 {m}" for m in SPATIAL) + " |")
        print("|---" * (len(CODES) + len(SPATIAL) + 1) + "|")
        for ratio in RATIOS:
            err = {}
            for name in CODES + SPATIAL:
                code = get_code(name if name in CODES else "ecc-22-10")
                method = "soft" if name in CODES else name
                e_sum = n_sum = 0
                for seed in args.seeds:
                    f, w, b, bd, col, lit = gen(code, ratio, seed, size)
                    d = decode(f, w, b, code, bit_depth=bd, method=method)
                    e_sum += int((((d.column != col) | ~d.valid) & lit).sum())
                    n_sum += int(lit.sum())
                    if gen_name == "edge.sim" and name in CODES:
                        pred[name].append(d.error[lit])
                        obs[name].append((np.abs(d.candidates[..., 0] - col) > 1)[lit])
                err[name] = e_sum / n_sum
            g = err["gray-10"]
            cells = [f"{err[c]:.4f}" + ("" if c == "gray-10" else f" ({g / max(err[c], 1e-9):.1f}x)") for c in CODES]
            cells += [f"{err[m]:.4f} ({err['ecc-22-10'] / max(err[m], 1e-9):.1f}x soft)" for m in SPATIAL]
            print(f"| {ratio} | " + " | ".join(cells) + " |", flush=True)
    print("\n## edge.sim: P(wrong) predicted / observed (column > 1 row off), per bin")
    for name in CODES:
        p, o = np.concatenate(pred[name]), np.concatenate(obs[name])
        cells = []
        for lo, hi in zip(BINS[:-1], BINS[1:]):
            s = (p >= lo) & (p < hi)
            if s.sum() >= 30:
                cells.append(f"[{lo:g}, {hi:g}) {p[s].mean():.4f} / {o[s].mean():.4f} ({int(s.sum())})")
        print(f"{name}: " + " | ".join(cells))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
