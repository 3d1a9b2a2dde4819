"""How far the published P(wrong) of `method="sgm"` can be trusted, next to `method="soft"`'s.

    python tools/eval_sgm_error.py [--size 160x120] [--seeds 0 1] [--ambient 1 2 4] [--out docs/results/sgm_error]

Captures: `tools/eval_posterior.py`'s two generators (edge.sim's flying scene and the tests'
plane / box / sphere renderer, 12-bit, fixed total exposure), at ambient = 1, 2 and 4 x the
projector, gray-10 and ecc-22-10, each decoded with `decode()`'s defaults and with
``method="sgm"`` (nothing else set).  Both methods publish a pixel where its P(wrong) is below
``max_error`` (0.01); a published pixel counts as wrong where its column is more than one row
off the true one (the observed error of `tools/eval_posterior.py`'s reliability table).

Per capture set and method: the share of lit pixels published, the share of published pixels
that are wrong against the share their P(wrong) predicts (its mean over them) and the ratio of
the two; then the published pixels binned by P(wrong) (below 1e-4, 1e-4 to 1e-3, 1e-3 to 1e-2):
errors seen against the count the bin's predictions expect (their sum), with the verdict on
"within 2x" of `edge.eval.report.calibration_verdict` (within; consistent at 99 % on the count;
off); and of sgm's wrong published pixels the share whose true column (within one row) was none
of its candidate states, the median of soft's P(wrong) there (what the pixel's own samples
say), and the share of sgm's wrong and of its right published pixels whose column is the state
candidate propagation added (`edge.decode.propagate`: a neighbour's track, not one of the pixel's
own top three; read by wrapping `edge.decode.decoder.propagate` for the call).  Writes README.md
to --out.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tools"))
sys.path.insert(0, str(ROOT))

import edge.decode.decoder as decoder  # noqa: E402
from edge.codes import get_code  # noqa: E402
from edge.commands._args import parse_size  # noqa: E402
from edge.decode import decode  # noqa: E402
from edge.eval.report import calibration_verdict  # noqa: E402
from eval_posterior import pbs_capture, sim_capture  # noqa: E402

CODES = ("gray-10", "ecc-22-10")
METHODS = ("soft", "sgm")
#: Bins of the published pixels' P(wrong) (all below max_error = 0.01).
EDGES = (0.0, 1e-4, 1e-3, 1e-2)


def published_errors(column: np.ndarray, valid: np.ndarray, error: np.ndarray, truth_col: np.ndarray,
                     lit: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(P(wrong), wrong) of the published lit pixels: float64 (P,) and bool (P,) where the column
    is more than one row off ``truth_col``."""
    where = valid & lit
    return error[where].astype(np.float64), np.abs(column[where].astype(np.int64) - truth_col[where]) > 1


@contextlib.contextmanager
def added_states(seen: list[np.ndarray]):
    """While open, every `edge.decode.decoder.propagate` call appends to ``seen`` its (H, W) int32
    added state's column (-1 where it added none: `Propagated.candidates[..., 3]`)."""
    original = decoder.propagate

    def spy(*args, **kwargs):
        out = original(*args, **kwargs)
        seen.append(np.where(out.extra, out.candidates[..., 3], -1).astype(np.int32))
        return out

    decoder.propagate = spy
    try:
        yield
    finally:
        decoder.propagate = original


def from_added_state(column: np.ndarray, top3: np.ndarray, added: np.ndarray) -> np.ndarray:
    """(H, W) bool where the published ``column`` is the added state's and none of the pixel's own
    top three (``top3`` (H, W, 3), the posterior's candidates)."""
    return (added >= 0) & (column == added) & ~(top3 == column[..., None]).any(axis=-1)


def bins(p: np.ndarray, wrong: np.ndarray) -> list[str]:
    """Per `EDGES` bin: ``seen / expected (pixels): verdict``."""
    cells = []
    for lo, hi in zip(EDGES[:-1], EDGES[1:]):
        s = (p >= lo) & (p < hi)
        expected, seen = float(p[s].sum()), int(wrong[s].sum())
        verdict = calibration_verdict(expected, seen) if s.any() else "-"
        cells.append(f"{seen} / {expected:.2f} ({int(s.sum())}): {verdict}")
    return cells


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", default="160x120", help="scene size WxH (default 160x120)")
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1], help="scene / noise seeds (default 0 1)")
    ap.add_argument("--ambient", type=float, nargs="+", default=[1.0, 2.0, 4.0],
                    help="ambient light as multiples of the projector's (default %(default)s)")
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "results" / "sgm_error",
                    help="folder for README.md (default docs/results/sgm_error)")
    args = ap.parse_args(argv)
    size = parse_size(args.size)
    if any(not a > 0 for a in args.ambient):
        raise ValueError(f"--ambient: expected positive multiples of the projector, got {args.ambient}")
    lines = [f"Command: `python tools/eval_sgm_error.py --size {args.size} --seeds {' '.join(map(str, args.seeds))} "
             f"--ambient {' '.join(f'{a:g}' for a in args.ambient)}`", ""]

    def say(text: str = "") -> None:
        print(text, flush=True)
        lines.append(text)

    say("Published pixels (P(wrong) < max_error = 0.01) of the lit ones; wrong: more than one row off.\n")
    say("| generator | ambient | code | method | published | wrong / predicted | ratio | "
        "P < 1e-4: seen / expected (pixels) | 1e-4 to 1e-3 | 1e-3 to 1e-2 | sgm's wrong: truth not a candidate | "
        "sgm's wrong: soft's P(wrong), median | sgm's wrong / right: the added state's column |")
    say("|---" * 13 + "|")
    for gen_name, gen in (("edge.sim", sim_capture), ("plane-box-sphere", pbs_capture)):
        for ratio in args.ambient:
            for name in CODES:
                code = get_code(name)
                caps = [gen(code, ratio, seed, size) for seed in args.seeds]
                lit_total = sum(int(c[5].sum()) for c in caps)
                softs = [decode(f, w, b, code, bit_depth=bits) for f, w, b, bits, _, _ in caps]
                for method in METHODS:
                    ps, ws, missed, own, added_wrong, added_right = [], [], [], [], [], []
                    for (f, w, b, bits, col, lit), soft in zip(caps, softs):
                        seen: list[np.ndarray] = []
                        with added_states(seen):
                            d = decode(f, w, b, code, bit_depth=bits, method=method)
                        p, wrong = published_errors(d.column, d.valid, d.error, col, lit)
                        ps.append(p)
                        ws.append(wrong)
                        bad = d.valid & lit & (np.abs(d.column.astype(np.int64) - col) > 1)
                        near = (np.abs(d.candidates.astype(np.int64) - col[..., None]) <= 1).any(axis=-1)
                        missed.append(~near[bad])
                        own.append(soft.error[bad])
                        if seen:  # method "sgm": the one propagate call of this decode
                            added = from_added_state(d.column, soft.candidates, seen[-1])
                            good = d.valid & lit & ~bad
                            added_wrong.append(added[bad])
                            added_right.append(added[good])
                    p, wrong, miss = np.concatenate(ps), np.concatenate(ws), np.concatenate(missed)
                    own_error = np.concatenate(own)
                    seen_share = float(wrong.mean()) if wrong.size else 0.0
                    predicted = float(p.mean()) if p.size else 0.0
                    ratio_cell = f"{seen_share / predicted:.1f}x" if predicted > 0 else "-"
                    sgm_rows = method == "sgm" and miss.size
                    not_cand = f"{miss.mean():.0%} of {miss.size}" if sgm_rows else "-"
                    own_cell = f"{np.median(own_error):.2g}" if sgm_rows else "-"
                    added_cell = (f"{np.concatenate(added_wrong).mean():.0%} / {np.concatenate(added_right).mean():.0%}"
                                  if sgm_rows else "-")
                    say(f"| {gen_name} | {ratio:g} | {name} | {method} | {p.size / max(lit_total, 1):.3f} | "
                        f"{seen_share:.4f} / {predicted:.5f} | {ratio_cell} | " + " | ".join(bins(p, wrong))
                        + f" | {not_cand} | {own_cell} | {added_cell} |")
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "README.md").write_text("# How far method=\"sgm\"'s P(wrong) can be trusted\n\n" + "\n".join(lines) + "\n")
    print(f"wrote {args.out / 'README.md'}")
    return 0


if __name__ == "__main__":
    from edge.cli import tool_main

    raise SystemExit(tool_main(main, __file__))
