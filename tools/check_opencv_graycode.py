"""Check `edge patterns write --layout opencv-graycode` against OpenCV's own GrayCodePattern.

opencv-contrib cannot share a virtual environment with opencv-python-headless (both install
``cv2``), so it is installed into a directory of its own and run in a child process:

    pip install --target /tmp/opencv-contrib --no-deps opencv-contrib-python-headless
    python tools/check_opencv_graycode.py --opencv-contrib /tmp/opencv-contrib

For each size and step, the child calls ``cv2.structured_light.GrayCodePattern.create(gw, gh)
.generate()`` for the grid ``((W - 1) // step + 1) x ((H - 1) // step + 1)``, blows each cell up to
step x step pixels and appends white and black (procam-calibration's gen_graycode_imgs.py);
the frames must equal `edge.patterns.opencv_graycode(W, H, step=step)` byte for byte.

With ``--capture DIR`` (an OpenCV Gray-code capture of a 1024x768 grid, default the shared
capture_0) it also decodes the capture with `edge decode-images` (column and row maps) and with
OpenCV's ``getProjPixel`` (white threshold 5, black threshold 40) on a random sample of pixels,
and counts where both resolve a pixel and disagree.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

CHILD = r"""
import sys
sys.path.insert(0, sys.argv[1])
import cv2, numpy as np
w, h, step, out = int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4]), sys.argv[5]
gw, gh = (w - 1) // step + 1, (h - 1) // step + 1
ok, pats = cv2.structured_light.GrayCodePattern.create(gw, gh).generate()
assert ok
ys, xs = np.arange(h) // step, np.arange(w) // step
frames = [np.asarray(p)[ys][:, xs] for p in pats]
frames += [np.full((h, w), 255, np.uint8), np.zeros((h, w), np.uint8)]
np.save(out, np.stack(frames))
print(cv2.__version__, cv2.__file__)
"""

CASES = ((1024, 768, 1), (1920, 1080, 2), (640, 480, 1), (100, 37, 3), (800, 600, 4))

PROJ_PIXEL_CHILD = r"""
import sys
sys.path.insert(0, sys.argv[1])
import glob, cv2, numpy as np
files = sorted(glob.glob(sys.argv[2] + "/*.png"))
imgs = [cv2.imread(f, cv2.IMREAD_GRAYSCALE) for f in files]
black, white = imgs[-1], imgs[-2]
g = cv2.structured_light.GrayCodePattern.create(1024, 768)
g.setWhiteThreshold(5)
g.setBlackThreshold(40)
pix = np.load(sys.argv[3])
out = np.full((len(pix), 2), -1, np.int64)
for i, (x, y) in enumerate(pix):
    if int(white[y, x]) - int(black[y, x]) <= 40:
        continue
    err, p = g.getProjPixel(imgs[:-2], int(x), int(y))
    if not err:
        out[i] = p
np.save(sys.argv[4], out)
"""


def check_capture(contrib: Path, capture: Path, sample: int) -> int:
    """Compare edge's column / row maps of ``capture`` with OpenCV's getProjPixel on ``sample`` pixels."""
    import cv2

    from edge.cli import main as edge_main

    with tempfile.TemporaryDirectory() as tmp:
        t = Path(tmp)
        rc = edge_main(["decode-images", str(capture), "--layout", "opencv-graycode", "--projector", "1024x768",
                        "--column-map", str(t / "c.png"), "--row-map", str(t / "r.png")])
        if rc != 0:
            return 2
        col = cv2.imread(str(t / "c.png"), cv2.IMREAD_UNCHANGED).astype(np.int64)
        row = cv2.imread(str(t / "r.png"), cv2.IMREAD_UNCHANGED).astype(np.int64)
        rng = np.random.default_rng(0)
        h, w = col.shape
        pix = np.stack([rng.integers(0, w, sample), rng.integers(0, h, sample)], axis=1)
        np.save(t / "pix.npy", pix)
        res = subprocess.run([sys.executable, "-c", PROJ_PIXEL_CHILD, str(contrib), str(capture), str(t / "pix.npy"),
                              str(t / "ocv.npy")], capture_output=True, text=True)
        if res.returncode != 0:
            print(f"OpenCV child failed: {res.stderr.strip().splitlines()[-1:]}")
            return 2
        ocv = np.load(t / "ocv.npy")
    ours = np.stack([col[pix[:, 1], pix[:, 0]], row[pix[:, 1], pix[:, 0]]], axis=1)
    ours_ok = (ours != 65535).all(axis=1)
    ocv_ok = (ocv >= 0).all(axis=1)
    both = ours_ok & ocv_ok
    diff = both & (ours != ocv).any(axis=1)
    print(f"{capture}: {sample} random pixels: edge resolves column and row of {ours_ok.mean() * 100:.1f} %, "
          f"OpenCV getProjPixel {ocv_ok.mean() * 100:.1f} %; both {both.sum()}, of which {diff.sum()} differ "
          f"({diff.sum() / max(both.sum(), 1) * 100:.2f} %)")
    return 0


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--opencv-contrib", required=True, type=Path,
                   help="directory holding opencv-contrib-python-headless (pip install --target DIR --no-deps ...)")
    p.add_argument("--capture", type=Path, default=None,
                   help="also compare decode-images with OpenCV's getProjPixel on this capture (1024x768 grid)")
    p.add_argument("--sample", type=int, default=3000, help="pixels sampled for --capture (default 3000)")
    a = p.parse_args(argv)
    from edge.patterns import opencv_graycode

    failures = 0
    with tempfile.TemporaryDirectory() as tmp:
        for w, h, step in CASES:
            out = Path(tmp) / f"{w}x{h}_{step}.npy"
            res = subprocess.run([sys.executable, "-c", CHILD, str(a.opencv_contrib), str(w), str(h), str(step), str(out)],
                                 capture_output=True, text=True)
            if res.returncode != 0:
                print(f"{w}x{h} step {step}: OpenCV child failed: {res.stderr.strip().splitlines()[-1:]}")
                return 2
            ref = np.load(out)
            ours = opencv_graycode(w, h, step=step)
            same = ref.shape == ours.shape and bool(np.array_equal(ref, ours))
            failures += not same
            print(f"{w}x{h} step {step}: OpenCV {res.stdout.split()[0]} {ref.shape[0]} frames, edge {ours.shape[0]} "
                  f"frames: {'identical' if same else 'DIFFERENT'}")
    if a.capture is not None and check_capture(a.opencv_contrib, a.capture, a.sample) != 0:
        return 2
    return 1 if failures else 0


if __name__ == "__main__":
    from edge.cli import tool_main

    raise SystemExit(tool_main(main, __file__))
