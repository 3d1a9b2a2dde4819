"""Metrics: error rate with thresholds, fraction decoded, RMSE, confusion against a valid mask."""

from __future__ import annotations

import numpy as np
import pytest

from edge.sim import error_map, error_rate, evaluate, make_scene


@pytest.fixture(scope="module")
def scene():
    return make_scene("steps", 64, 16, seed=0)


def test_perfect_decode_has_zero_error_and_zero_rmse(scene):
    m = evaluate(scene.column_int.copy(), scene)
    assert m.error_rate == 0.0 and m.fraction_decoded == 1.0 and m.wrong_rate == 0.0
    assert m.rmse_mm < 15.0  # only the half-column rounding of the true column (up to 1.6 m)
    assert m.pixels == int(scene.lit.sum())


def test_thresholds_and_invalid_pixels(scene):
    col = scene.column_int.copy()
    lit = np.argwhere(scene.lit)
    col[tuple(lit[0])] += 1
    col[tuple(lit[1])] -= 2
    col[tuple(lit[2])] += 5
    col[tuple(lit[3])] = -1
    n = scene.lit.sum()
    assert error_rate(col, scene) == pytest.approx(4 / n)
    assert error_rate(col, scene, threshold=1) == pytest.approx(3 / n)
    assert error_rate(col, scene, threshold=2) == pytest.approx(2 / n)
    m = evaluate(col, scene, threshold=0)
    assert m.fraction_decoded == pytest.approx((n - 1) / n) and m.wrong_rate == pytest.approx(3 / n)
    assert error_map(col, scene).sum() == 4
    # unlit pixels never count, whatever is decoded there
    col2 = scene.column_int.copy()
    col2[~scene.lit] = 7
    assert error_rate(col2, scene) == 0.0


def test_stripe_truth_and_rmse_grows_with_error(scene):
    assert error_rate(np.where(scene.lit, scene.column_int // 4, -1).astype(np.int32), scene, stripe=4) == 0.0
    off = np.where(scene.lit, scene.column_int + 3, -1).astype(np.int32)
    assert evaluate(off, scene).rmse_mm > evaluate(scene.column_int, scene).rmse_mm + 5


def test_confusion_against_valid_mask(scene):
    col = scene.column_int.copy()
    lit = np.argwhere(scene.lit)
    wrong = tuple(lit[:10].T)
    col[wrong] += 3
    valid = scene.lit.copy()
    rejected_right = tuple(lit[10:15].T)
    valid[rejected_right] = False
    n = scene.lit.sum()
    m = evaluate(col, scene, valid=valid)
    assert m.wrongly_valid == pytest.approx(10 / n) and m.wrongly_rejected == pytest.approx(5 / n)
    valid[wrong] = False
    m2 = evaluate(col, scene, valid=valid)
    assert m2.wrongly_valid == 0.0


def test_bad_metric_input(scene):
    with pytest.raises(ValueError, match="shape"):
        evaluate(np.zeros((3, 3), np.int32), scene)
    with pytest.raises(ValueError, match="integers"):
        evaluate(scene.column.copy(), scene)
    with pytest.raises(ValueError, match="threshold must be >= 0"):
        error_rate(scene.column_int, scene, threshold=-1)
