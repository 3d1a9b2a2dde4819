"""Pattern sets that round-trip: OpenCV's Gray-code layout and edge codes with a manifest.

OpenCV GrayCodePattern is checked against its documented definition here (opencv-contrib cannot
share an environment with opencv-python-headless; tools/check_opencv_graycode.py compares with
OpenCV's own generate() from a separate install).  Every layout is written with
`edge patterns write`, read back from files by `edge decode-images`, and must give the exact
column (and row) per pixel.
"""

from __future__ import annotations

import json
import math
import shutil

import cv2
import numpy as np
import pytest

from edge.cli import main
from edge.codes import get_code
from edge.patterns import opencv_graycode, parse_manifest, read_manifest
from edge.sim import CameraModel, capture, make_scene


def _gray(v: np.ndarray) -> np.ndarray:
    return v ^ (v >> 1)


@pytest.mark.parametrize("w,h,step", [(1024, 768, 1), (100, 37, 3), (1920, 1080, 2)])
def test_opencv_graycode_matches_definition(w, h, step):
    frames = opencv_graycode(w, h, step=step)
    gw, gh = (w - 1) // step + 1, (h - 1) // step + 1
    bc, br = math.ceil(math.log2(gw)), math.ceil(math.log2(gh))
    assert frames.shape == (2 * (bc + br) + 2, h, w) and frames.dtype == np.uint8
    gx = _gray(np.arange(w) // step)
    gy = _gray(np.arange(h) // step)
    for i in range(bc):  # column bits, MSB first, pattern then inverse
        bit = ((gx >> (bc - 1 - i)) & 1).astype(np.uint8) * 255
        np.testing.assert_array_equal(frames[2 * i], np.broadcast_to(bit, (h, w)))
        np.testing.assert_array_equal(frames[2 * i + 1], 255 - frames[2 * i])
    for i in range(br):  # then the row bits
        bit = ((gy >> (br - 1 - i)) & 1).astype(np.uint8) * 255
        np.testing.assert_array_equal(frames[2 * (bc + i)], np.broadcast_to(bit[:, None], (h, w)))
        np.testing.assert_array_equal(frames[2 * (bc + i) + 1], 255 - frames[2 * (bc + i)])
    assert frames[-2].min() == 255 and frames[-1].max() == 0
    if (w, h, step) == (1024, 768, 1):
        assert frames.shape[0] == 42  # the shared capture's layout


def _read_map(path):
    m = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    assert m.dtype == np.uint16
    return m


@pytest.mark.parametrize("step", [1, 3])
def test_opencv_layout_write_then_decode_is_identity(tmp_path, step, capsys):
    w, h = 200, 120
    pats = tmp_path / "pats"
    assert main(["patterns", "write", "--layout", "opencv-graycode", "--size", f"{w}x{h}", "--graycode-step",
                 str(step), str(pats)]) == 0
    gw, gh = (w - 1) // step + 1, (h - 1) // step + 1
    n = 2 * (math.ceil(math.log2(gw)) + math.ceil(math.log2(gh))) + 2
    assert sorted(p.name for p in pats.glob("*.png")) == [f"pattern_{i:02d}.png" for i in range(n)]
    m = read_manifest(pats / "manifest.json")
    assert m.layout == "opencv-graycode" and m.stripe == step and m.axes["columns"].cells == gw
    for i, name in enumerate(sorted(p.name for p in pats.glob("*.png"))):
        np.testing.assert_array_equal(cv2.imread(str(pats / name), cv2.IMREAD_UNCHANGED),
                                      opencv_graycode(w, h, step=step)[i])
    # the projected frames themselves as the capture (camera pixel = projector pixel)
    xs, ys = np.meshgrid(np.arange(w), np.arange(h))
    want_c, want_r = step * (xs // step), step * (ys // step)
    # 1) through the manifest (auto-detected): the step comes from it
    assert main(["decode-images", str(pats), "--column-map", str(tmp_path / "c.png"),
                 "--row-map", str(tmp_path / "r.png")]) == 0
    assert "layout manifest" in capsys.readouterr().out
    np.testing.assert_array_equal(_read_map(tmp_path / "c.png"), want_c)
    np.testing.assert_array_equal(_read_map(tmp_path / "r.png"), want_r)
    # 2) as a plain OpenCV capture in file-name order: --projector is the grid, --graycode-step the step
    assert main(["decode-images", str(pats), "--layout", "opencv-graycode", "--projector", f"{gw}x{gh}",
                 "--graycode-step", str(step), "--column-map", str(tmp_path / "c2.png"),
                 "--row-map", str(tmp_path / "r2.png")]) == 0
    np.testing.assert_array_equal(_read_map(tmp_path / "c2.png"), want_c)
    np.testing.assert_array_equal(_read_map(tmp_path / "r2.png"), want_r)


def test_patterns_write_opencv_rejects_edge_options(tmp_path, capsys):
    assert main(["patterns", "write", "--layout", "opencv-graycode", "--code", "gray-10", str(tmp_path / "a")]) == 2
    assert "--code: does not apply" in capsys.readouterr().err
    assert main(["patterns", "write", "--layout", "opencv-graycode", "--size", "1x1", str(tmp_path / "b")]) == 2
    assert "2x2 cells" in capsys.readouterr().err


@pytest.mark.parametrize("code,orientation,inverse", [("ecc-22-10", "columns", False),
                                                      ("xor02-10+crc5", "both", True)])
def test_edge_code_manifest_round_trip_through_the_simulator(tmp_path, code, orientation, inverse, capsys):
    """Render a layout, "capture" its PNG frames with the simulator, write the captures as PNG and
    decode them from the files; the decoded columns (and rows) must be the scene's."""
    scene = make_scene("flying", 320, 240, seed=3)  # occlusions: about 9 % of the pixels unlit
    pw = int(scene.geometry.projector_width)
    pats = tmp_path / "pats"
    argv = ["patterns", "write", "--code", code, "--size", f"{pw}x{scene.height}", "--orientation", orientation]
    assert main(argv + (["--inverse"] if inverse else []) + [str(pats)]) == 0
    manifest = json.loads((pats / "manifest.json").read_text())
    names = [f["file"] for f in manifest["frames"]]
    assert manifest["format"] == "edge-patterns/1" and set(p.name for p in pats.glob("*.png")) == set(names)
    roles = [f["role"] for f in manifest["frames"]]
    n = get_code(code).n * (2 if orientation == "both" else 1) * (2 if inverse else 1)
    assert roles.count("white") == roles.count("black") == 1 and len(roles) == n + 2
    projected = np.stack([cv2.imread(str(pats / nm), cv2.IMREAD_UNCHANGED) for nm in names])
    frames = capture(scene, projected, CameraModel(), rng=np.random.default_rng(1), exposure=1.0)
    cap = tmp_path / "capture"
    cap.mkdir()
    for nm, img in zip(names, frames):
        assert cv2.imwrite(str(cap / nm), img)
    shutil.copy(pats / "manifest.json", cap / "manifest.json")
    # the manifest names the capture's images, so an output may go into its folder
    argv = ["decode-images", str(cap), "--column-map", str(cap / "c.png")]
    if orientation == "both":
        argv += ["--row-map", str(tmp_path / "r.png")]
    assert main(argv) == 0
    assert "layout manifest" in capsys.readouterr().out
    col = _read_map(cap / "c.png").astype(np.int64)
    lit = scene.lit & (scene.column_int >= 0)
    valid = (col != 65535) & lit
    assert valid.sum() >= 0.9 * lit.sum()
    assert (col[valid] == scene.column_int[valid]).mean() >= 0.995
    assert ((col != 65535) & ~scene.lit).sum() <= 0.01 * col.size
    if orientation == "both":  # rectified simulator: camera row y sees projector row y
        row = _read_map(tmp_path / "r.png").astype(np.int64)
        ys = np.broadcast_to(np.arange(scene.height)[:, None], row.shape)
        rvalid = (row != 65535) & lit
        assert rvalid.sum() >= 0.9 * lit.sum()
        assert (row[rvalid] == ys[rvalid]).mean() >= 0.995


def test_manifest_captures_with_other_suffix_and_legacy_manifest(tmp_path, capsys):
    pats = tmp_path / "pats"
    assert main(["patterns", "write", "--code", "gray-8", "--size", "256x4", str(pats)]) == 0
    cap = tmp_path / "cap"
    cap.mkdir()
    for p in pats.glob("*.png"):  # captures saved as TIFF under the frames' names
        assert cv2.imwrite(str(cap / (p.stem + ".tif")), np.repeat(cv2.imread(str(p), cv2.IMREAD_UNCHANGED), 2, axis=0))
    m = json.loads((pats / "manifest.json").read_text())
    legacy = {k: m[k] for k in ("code", "width", "height", "stripe", "orientation", "columns_used", "patterns",
                                "white", "black")}
    (tmp_path / "legacy.json").write_text(json.dumps(legacy))
    spec = parse_manifest(legacy)
    assert spec.axes["columns"].patterns == tuple(m["patterns"]) and spec.white == "white.png"
    assert main(["decode-images", str(cap), "--manifest", str(tmp_path / "legacy.json"),
                 "--column-map", str(tmp_path / "c.png")]) == 0
    np.testing.assert_array_equal(_read_map(tmp_path / "c.png"), np.broadcast_to(np.arange(256), (8, 256)))
    capsys.readouterr()
    (cap / "pattern_03.tif").unlink()
    assert main(["decode-images", str(cap), "--manifest", str(pats / "manifest.json"),
                 "--column-map", str(tmp_path / "c.png")]) == 2
    assert "pattern_03" in capsys.readouterr().err
    (tmp_path / "bad.json").write_text("{not json")
    assert main(["decode-images", str(cap), "--manifest", str(tmp_path / "bad.json")]) == 2
    assert "expected a JSON manifest" in capsys.readouterr().err
    bad = dict(m, frames=m["frames"][:-1])  # no black frame
    (tmp_path / "bad2.json").write_text(json.dumps(bad))
    assert main(["decode-images", str(cap), "--manifest", str(tmp_path / "bad2.json")]) == 2
    assert "exactly one black frame" in capsys.readouterr().err
    # columns only: no depth possible, and the command says so
    assert main(["decode-images", str(pats), "--row-map", str(tmp_path / "r.png")]) == 2
    assert "codes no projector rows" in capsys.readouterr().err
