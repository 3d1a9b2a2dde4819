"""Check `edge patterns write --layout opencv-graycode` against OpenCV's own GrayCodePattern.

opencv-contrib cannot share a virtual environment with opencv-python-headless (both install
``cv2``), so it is installed into a directory of its own and run in a child process:

    pip install --target /tmp/opencv-contrib --no-deps opencv-contrib-python-headless
    python tools/check_opencv_graycode.py --opencv-contrib /tmp/opencv-contrib

For each size and step, the child calls ``cv2.structured_light.GrayCodePattern.create(gw, gh)
.generate()`` for the grid ``((W - 1) // step + 1) x ((H - 1) // step + 1)``, blows each cell up to
step x step pixels and appends white and black (procam-calibration's gen_graycode_imgs.py);
the frames must equal `edge.patterns.opencv_graycode(W, H, step=step)` byte for byte.
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


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--opencv-contrib", required=True, type=Path,
                   help="directory holding opencv-contrib-python-headless (pip install --target DIR --no-deps ...)")
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
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
