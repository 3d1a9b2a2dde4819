"""Real OpenCV Gray-code capture (../shared/data/procam-graycode/capture_0), full resolution.

OpenCV's own decoder (white threshold 5, black threshold 40) resolves about 56% of the pixels
with about 0.01% errors (README of the data set; opencv-contrib is not installed here).  Our
default valid mask must resolve at least 1.15x OpenCV's pixel count (>= 64.4% of all pixels)
at an error rate of at most 1.5x OpenCV's (<= 0.015%).  Error: a valid column differing by more
than 2 from the median of the valid columns in its 7x7 neighbourhood.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from _tools import load_tool
from edge.decode import decode, load_opencv_graycode, spatial_outliers

REPO = Path(__file__).resolve().parents[1]
CAPTURE = load_tool("real_data").REAL_CAPTURE  # beside the repository, or under $EDGE_SHARED_DIR
OPENCV_RESOLVED = 0.56
OPENCV_ERROR_RATE = 0.0001

pytestmark = pytest.mark.skipif(not CAPTURE.is_dir(), reason=f"real capture not found at {CAPTURE}")


@pytest.fixture(scope="module")
def capture():
    return load_opencv_graycode(CAPTURE, (1024, 768))


def test_layout(capture):
    assert capture.frames.shape == (10, 1024, 1280) and capture.inverse.shape == capture.frames.shape
    assert capture.code.name == "gray-10" and capture.columns == 1024
    assert capture.white.mean() > capture.black.mean() + 30


def test_default_mask_beats_opencv(capture):
    d = decode(capture.frames, capture.white, capture.black, capture.code, inverse=capture.inverse,
               columns=capture.columns)
    resolved = d.valid.mean()
    errors = spatial_outliers(d.column, d.valid, window=7, tol=2)
    rate = errors.sum() / d.valid.sum()
    print(f"resolved {resolved:.4f}, error rate {rate:.6f} ({errors.sum()} pixels)")
    assert resolved >= 1.15 * OPENCV_RESOLVED
    assert rate <= 1.5 * OPENCV_ERROR_RATE
    # soft ML decoding without the valid mask agrees with a plain pattern-vs-inverse decode
    bits = (capture.frames > capture.inverse).astype(np.int64)
    g = np.zeros(bits.shape[1:], np.int64)
    for b in bits:
        g = (g << 1) | b
    plain = g.copy()
    shift = 1
    while shift < 16:
        plain ^= plain >> shift
        shift <<= 1
    strong = d.confidence >= 0.5
    assert (d.candidates[..., 0][strong] == plain[strong]).mean() > 0.999


def test_cli_writes_pngs(tmp_path):
    out = tmp_path / "col.png"
    res = subprocess.run(
        [sys.executable, "-m", "edge.cli", "decode-images", str(CAPTURE), "--layout", "opencv-graycode",
         "--projector", "1024x768", "--out", str(out)], capture_output=True, text=True, cwd=REPO,
    )
    assert res.returncode == 0, res.stderr
    import cv2

    col = cv2.imread(str(out))
    conf = cv2.imread(str(tmp_path / "col_confidence.png"), cv2.IMREAD_UNCHANGED)
    assert col.shape == (1024, 1280, 3) and conf.shape == (1024, 1280)
    assert (col.reshape(-1, 3).max(1) > 0).mean() > 0.6


def test_cli_bad_directory(tmp_path):
    (tmp_path / "empty").mkdir()
    res = subprocess.run([sys.executable, "-m", "edge.cli", "decode-images", str(tmp_path / "empty"), "--out",
                          str(tmp_path / "c.png")], capture_output=True, text=True, cwd=REPO)
    assert res.returncode == 2 and "expected 42 images" in res.stderr
