"""Pattern rendering, calibration frames, PNG export and the codes / patterns CLI."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from edge.cli import main
from edge.codes import get_code
from edge.patterns import calibration, column_rows, render, symbol_levels, write_patterns


def test_render_shape_and_values():
    code = get_code("ecc-22-10")
    frames = render(code, 1024, 8)
    assert frames.shape == (22, 8, 1024) and frames.dtype == np.uint8
    assert set(np.unique(frames)) == {0, 255}
    np.testing.assert_array_equal(frames[:, 3, :].T, code.codebook * 255)
    assert np.all(frames == frames[:, :1, :])  # columns are constant down the image


def test_render_stripe_and_non_power_of_two_width():
    code = get_code("gray-10")
    frames = render(code, 912, 4, stripe=1)
    np.testing.assert_array_equal(frames[:, 0, :].T, code.codebook[:912] * 255)
    wide = render(code, 1280, 2, stripe=2)
    np.testing.assert_array_equal(wide[:, 0, 0::2], wide[:, 0, 1::2])
    np.testing.assert_array_equal(wide[:, 0, 0::2].T, code.codebook[:640] * 255)
    np.testing.assert_array_equal(column_rows(code, 5, 2), [0, 0, 1, 1, 2])
    odd = render(code, 7, 1, stripe=3)  # last stripe cut: columns 6 -> row 2
    np.testing.assert_array_equal(odd[:, 0, 6], code.codebook[2] * 255)


def test_render_rows_orientation():
    code = get_code("gray-8")
    frames = render(code, 3, 256, orientation="rows")
    assert frames.shape == (8, 256, 3)
    np.testing.assert_array_equal(frames[:, :, 1].T, code.codebook * 255)


def test_nary_levels():
    np.testing.assert_array_equal(symbol_levels(3), [0, 128, 255])
    assert symbol_levels(8)[-1] == 255 and symbol_levels(8)[1] == 36
    code = get_code("ternary-golay-12-6")
    frames = render(code, 729, 1)
    assert set(np.unique(frames)) == {0, 128, 255}
    np.testing.assert_array_equal(frames[:, 0, :].T, symbol_levels(3)[code.codebook])


def test_calibration():
    white, black = calibration(640, 480)
    assert white.shape == black.shape == (480, 640)
    assert white.dtype == np.uint8 and white.min() == 255 and black.max() == 0


@pytest.mark.parametrize("kwargs,match", [
    (dict(width=1025, height=4), "larger than the 1024 codewords"),
    (dict(width=2049, height=4, stripe=2), "times stripe 2"),
    (dict(width=0, height=4), "positive integer"),
    (dict(width=64, height=4, stripe=0), "stripe"),
    (dict(width=64, height=4, orientation="diagonal"), "orientation"),
])
def test_render_bad_input(kwargs, match):
    with pytest.raises(ValueError, match=match):
        render(get_code("gray-10"), **kwargs)


def test_write_patterns_refuses_a_stripe_that_leaves_one_cell(tmp_path, capsys):
    # one cell sent one codeword to every projector column: a set that decodes nothing, written with exit 0
    for kwargs, match in [(dict(width=64, height=8, stripe=1000), "64 pixels wide gets one code cell"),
                          (dict(width=64, height=8, stripe=64), "at most 63 pixels"),
                          (dict(width=64, height=8, stripe=8, orientation="both"), "8 pixels high")]:
        with pytest.raises(ValueError, match=match):
            write_patterns(get_code("gray-10"), tmp_path / "set", **kwargs)
        assert not (tmp_path / "set").exists()
    assert write_patterns(get_code("gray-10"), tmp_path / "set", 64, 8, stripe=63)["columns_used"] == 2
    assert main(["patterns", "write", "--code", "gray-10", "--size", "64x8", "--stripe", "1000",
                 str(tmp_path / "cli")]) == 2
    assert "one code cell" in capsys.readouterr().err and not (tmp_path / "cli").exists()


def test_write_patterns(tmp_path):
    code = get_code("ecc-22-10")
    manifest = write_patterns(code, tmp_path, 100, 20, stripe=2)
    assert manifest["patterns"][0] == "pattern_00.png" and len(manifest["patterns"]) == 22
    assert json.loads((tmp_path / "manifest.json").read_text())["d_min"] == 8
    frames = render(code, 100, 20, stripe=2)
    for i in (0, 21):
        img = cv2.imread(str(tmp_path / f"pattern_{i:02d}.png"), cv2.IMREAD_UNCHANGED)
        np.testing.assert_array_equal(img, frames[i])
    assert cv2.imread(str(tmp_path / "white.png"), cv2.IMREAD_UNCHANGED).min() == 255
    assert cv2.imread(str(tmp_path / "black.png"), cv2.IMREAD_UNCHANGED).max() == 0


def test_cli_patterns_write(tmp_path, capsys):
    assert main(["patterns", "write", "--code", "ecc-22-10", "--size", "1024x768", str(tmp_path)]) == 0
    assert len(list(tmp_path.glob("pattern_*.png"))) == 22
    assert main(["patterns", "write", "--code", "gray-10", "--size", "2048x768", str(tmp_path / "x")]) == 2
    assert "larger than" in capsys.readouterr().err
    assert main(["patterns", "write", "--size", "big", str(tmp_path / "y")]) == 2
    assert "--size expects WIDTHxHEIGHT" in capsys.readouterr().err and not (tmp_path / "y").exists()
    assert not (tmp_path / "x").exists()  # the refused 2048-wide set wrote nothing either


def test_cli_codes(capsys):
    assert main(["codes", "show", "ecc-22-10"]) == 0
    out = capsys.readouterr().out
    assert "d_min         8" in out and "max 8  mean 8.000" in out and "8: 330" in out
    assert main(["codes", "table", "--k", "10", "--no-progress"]) == 0
    out = capsys.readouterr().out
    assert any(line.split()[:5] == ["10", "31", "12", "12", "12"] for line in out.splitlines())
    assert main(["codes", "edc-search", "--base", "xor02-10", "--widths", "5"]) == 0
    assert "best: CRC-5 0x15" in capsys.readouterr().out
    assert main(["codes", "show", "no-such-code"]) == 2
    assert main(["codes", "edc-search", "--widths", "2-4"]) == 2


def test_a_second_set_refuses_or_replaces_the_first(tmp_path, capsys):
    """Writing a shorter set into a directory that held a longer one left the old pattern_*.png
    behind (22 ecc-22-10 frames, then 10 gray-10 frames: 12 stale ones a slideshow would project)."""
    from edge.cli import main

    d = tmp_path / "set"
    assert main(["patterns", "write", "--size", "64x48", "--code", "ecc-22-10", str(d)]) == 0
    assert main(["patterns", "write", "--size", "64x48", "--code", "gray-10", str(d)]) == 2
    assert "holds a pattern set already" in capsys.readouterr().err
    assert len(list(d.glob("pattern_*.png"))) == 22  # refused: nothing touched
    (d / "notes.txt").write_text("mine")
    assert main(["patterns", "write", "--size", "64x48", "--code", "gray-10", "--overwrite", str(d)]) == 0
    assert sorted(p.name for p in d.glob("pattern_*.png")) == [f"pattern_{i:02d}.png" for i in range(10)]
    assert (d / "notes.txt").read_text() == "mine"  # only the set's own files are replaced
