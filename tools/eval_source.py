"""Figures and tables for light-source coding (paper section 5) into docs/results/source/.

    python tools/eval_source.py [--out docs/results/source] [--size 320x240]

Writes codes.txt (correlation reports), event_sl.txt + event_sl.png (event frames and disparity with and
without coding under interference and 100 Hz ambient flicker), curtain.txt + curtain.png (two light
curtains, uncoded vs 1100/0101).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import cv2
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from edge.codes.source import correlation_report, family, source_code  # noqa: E402
from edge.commands._args import output_dir, parse_size  # noqa: E402
from edge.eval.curtain import run_curtain  # noqa: E402
from edge.eval.event_sl import run_label, scenarios  # noqa: E402
from edge.source.curtain import CurtainConfig  # noqa: E402
from edge.source.event_sl import EventSLConfig  # noqa: E402


def codes_report(out: Path) -> None:
    lines = ["# paper codes (frame kind)", correlation_report([source_code(c) for c in ("1100", "0101")]),
             correlation_report([source_code(c) for c in ("1101", "1010")]),
             "# paper event code vs plain on/off (event kind)",
             correlation_report([source_code("10100010"), source_code("10")], "event")]
    for n, length in [(2, 6), (3, 6), (3, 8), (4, 8), (6, 10)]:
        lines += [f"# family({n}, {length}) frame", correlation_report(family(n, length))]
    lines += ["# family(4, 8) event", correlation_report(family(4, 8, "event"), "event")]
    (out / "codes.txt").write_text("\n".join(lines) + "\n")


def event_sl(out: Path, w: int, h: int) -> None:
    cfg = EventSLConfig(width=w, height=h, flicker_hz=100.0)
    runs = scenarios(cfg)
    rows = [(f"{run_label(cfg, coded)}, {name}", m) for coded, name, _, m in runs]
    panels = [(coded, res) for coded, name, res, _ in runs if name == "interference"]
    lines = ["| run | own events kept | foreign rejected | flicker rejected | valid | disparity MAE (px) | bad >1px | agrees with clean (1 px) |",
             "|---|---|---|---|---|---|---|---|"]
    for name, m in rows:
        lines.append(f"| {name} | {m['own_kept']:.3f} | {m['interference_rejected']:.3f} | {m['ambient_rejected']:.3f} | "
                     f"{m['valid']:.3f} | {m['mae_px']:.3f} | {m['bad1']:.3f} | {m.get('agree1', float('nan')):.3f} |")
    (out / "event_sl.txt").write_text("\n".join(lines) + "\n")
    fig, ax = plt.subplots(2, 3, figsize=(12, 6.5))
    lo, hi = panels[0][1].band
    for r, (coded, res) in enumerate(panels):
        title = f"coded {cfg.code} + matched filter" if coded else "uncoded 10, all events"
        k = 2
        allev = np.zeros((h, w), np.int32)
        np.add.at(allev, (res.events["y"][res.period == k], res.events["x"][res.period == k]), 1)
        ax[r, 0].imshow(np.minimum(allev, 3), cmap="gray")
        ax[r, 0].set_title(f"{'coded' if coded else 'uncoded'}: all events (period {k})")
        ax[r, 1].imshow(res.frames[k] > 0, cmap="gray")
        ax[r, 1].set_title(f"{title}: event frame")
        im = ax[r, 2].imshow(res.disparity[k], vmin=lo, vmax=hi, cmap="turbo")
        ax[r, 2].set_title("disparity (SGBM vs reference dots)")
        fig.colorbar(im, ax=ax[r, 2], fraction=0.04)
    for a in ax.ravel():
        a.axis("off")
    fig.suptitle("Event-camera SL with a foreign dot projector (1.3 ms slots) and 100 Hz ambient flicker")
    fig.tight_layout()
    fig.savefig(out / "event_sl.png", dpi=90)
    plt.close(fig)


def curtain(out: Path, w: int, h: int) -> None:
    cfg = CurtainConfig(width=w, height=h)
    runs = [("uncoded, device 1 alone", ("1",), 0.0), ("uncoded, two devices", ("1", "1"), 0.0)]
    runs += [(f"1100 / 0101, phase {p} slots", ("1100", "0101"), p) for p in (0, 1, 2, 3, 0.5)]
    fam = tuple(c.string for c in family(3, 6))
    runs += [(f"family(3,6) {'/'.join(fam)}, phases 1.5, 4", fam, (1.5, 4.0))]
    lines = ["| run | false detections | false-detection rate | missed detections | missed-detection rate |",
             "|---|---|---|---|---|"]
    images = {}
    for name, codes, phase in runs:
        r = run_curtain(cfg, codes, phase_slots=phase)
        q = r.rates()
        lines.append(f"| {name} | {q['false_detections']} | {q['false_detection_rate']:.4f} | {q['missed_detections']} | "
                     f"{q['missed_detection_rate']:.4f} |")
        images[name] = r
    (out / "curtain.txt").write_text("\n".join(lines) + "\n")
    tiles = []
    for name in ("uncoded, device 1 alone", "uncoded, two devices", "1100 / 0101, phase 1 slots"):
        r = images[name]
        img = np.zeros(r.detected.shape + (3,), np.uint8)
        img[r.detected & r.truth] = (255, 255, 255)
        img[r.detected & ~r.truth] = (0, 0, 255)  # false detections in red (BGR)
        img[~r.detected & r.truth] = (255, 128, 0)  # missed in blue
        img = cv2.resize(img, None, fx=2, fy=2, interpolation=cv2.INTER_NEAREST)
        bar = np.full((28, img.shape[1], 3), 40, np.uint8)
        cv2.putText(bar, name, (6, 20), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (255, 255, 255), 1, cv2.LINE_AA)
        tiles.append(np.vstack([bar, img]))
        tiles.append(np.full((tiles[-1].shape[0], 6, 3), 128, np.uint8))
    cv2.imwrite(str(out / "curtain.png"), np.hstack(tiles[:-1]))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default=str(Path(__file__).resolve().parents[1] / "docs" / "results" / "source"),
                    help="output folder (default docs/results/source)")
    ap.add_argument("--size", default="320x240", help="scene size WxH (default 320x240)")
    args = ap.parse_args()
    w, h = parse_size(args.size, minimum=16)  # as `edge source event-demo` / `curtain-demo`
    out = output_dir(args.out)
    codes_report(out)
    event_sl(out, w, h)
    curtain(out, w, h)
    for f in ("event_sl.txt", "curtain.txt"):
        print(f"== {f}\n" + (out / f).read_text())
    return 0


if __name__ == "__main__":
    from edge.cli import tool_main

    raise SystemExit(tool_main(main, __file__))
