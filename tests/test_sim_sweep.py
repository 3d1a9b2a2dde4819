"""Evaluation sweep plumbing: message re-ordering, a tiny sweep, the report files."""

from __future__ import annotations

import numpy as np
import pytest

from edge.codes import get_code
from edge.eval.sweep import BANDS, SweepConfig, claims, edge_decoder, reorder, run_sweep, write_report


def test_reorder_keeps_the_encoder_and_changes_only_the_column_order():
    code = get_code("ecc-22-10")
    binary = reorder(code, "binary")
    gray = reorder(code, "gray")
    assert np.array_equal(gray.codebook, code.codebook)
    assert binary.d_min == code.d_min and not np.array_equal(binary.codebook, code.codebook)
    assert sorted(map(bytes, binary.codebook)) == sorted(map(bytes, code.codebook))
    # Gray order: neighbouring columns differ in d_min..n bits; binary order has bigger jumps on average
    assert binary.neighbour_distances().mean() > gray.neighbour_distances().mean()
    with pytest.raises(ValueError, match="order must be"):
        reorder(code, "random")


def test_tiny_sweep_writes_plots_table_and_claims(tmp_path):
    decoder = edge_decoder()  # edge.decode is part of the package: a broken install fails here
    cfg = SweepConfig(width=64, height=48, seeds=(0,), ratios=(0.05, 2.0), experiments=("soft_quant",))
    rows = run_sweep(cfg, decoder, progress=False)
    assert len(rows) == 2 * 4 * 2
    by = {(r.series, r.x): r.error_rate for r in rows}
    for ss in (0.015, 0.04):
        assert by[(f"gray-10 s={ss}", 2.0)] < by[(f"gray-10 s={ss}", 0.05)]
    # the coding gain with the defaults (2.5 % vs 0.07 % here)
    assert 3 * by[("ecc-22-10 s=0.04", 2.0)] < by[("gray-10 s=0.04", 2.0)]
    assert all(0.0 <= r.error_rate <= 1.0 and r.pixels > 1000 for r in rows)
    for r in rows:  # per-albedo-band error rates add up to the overall one
        assert len(r.band_error) == len(BANDS) and sum(r.band_pixels) == r.pixels
        total = sum(e * p for e, p in zip(r.band_error, r.band_pixels) if p)
        assert total == pytest.approx(r.error_rate * r.pixels, abs=0.5)
    path = write_report(rows, tmp_path, cfg, command="test", decoder_name="edge.decode", seconds=0.0,
                        preamble="## Findings\n\nhand-written")
    text = path.read_text()
    assert (tmp_path / "soft_quant.png").stat().st_size > 1000 and (tmp_path / "results.json").exists()
    assert "| gray-10 s=0.04 |" in text and "Paper claims" in text and "## Findings" in text
    assert "| gray-10 s=0.04 [albedo < 0.3] |" in text
    assert len(claims(rows)) == 4 and all(c["agree"] in ("yes", "partly", "no") for c in claims(rows))


def test_levels_experiment_pairs_noise_and_self_calibration_beats_the_calibration_frames():
    decoder = edge_decoder()
    cfg = SweepConfig(width=64, height=48, seeds=(0,), ratios=(0.4,), experiments=("levels", "soft_quant"))
    rows = run_sweep(cfg, decoder, progress=False)
    by = {(r.experiment, r.series): r.error_rate for r in rows}
    # same capture, same noise, same (default) settings: the levels experiment's self-calibrated row
    # equals soft_quant's row
    assert by[("levels", "ecc-22-10 self-calibrated")] == by[("soft_quant", "ecc-22-10 s=0.04")]
    for name in ("gray-10", "ecc-22-10", "ecc-63-10"):
        assert by[("levels", f"{name} oracle")] <= by[("levels", f"{name} calibration")]
    # the codes with many frames: the default self-calibration beats the single calibration frames
    # at exposure T/n (here 13.3 vs 14.4 % and 12.6 vs 20.8 %), and for ecc-63-10 it recovers
    # nearly all of what noise-free calibration frames would give.  (gray-10 is not asserted: here
    # its self-calibration is 1.4 points worse than its calibration frames, 47.7 vs 46.3 %; in the
    # full sweep the two are within 0.5 points, see docs/results/eval/README.md.)
    for name in ("ecc-22-10", "ecc-63-10"):
        assert by[("levels", f"{name} self-calibrated")] < by[("levels", f"{name} calibration")]
    oracle, cal = by[("levels", "ecc-63-10 oracle")], by[("levels", "ecc-63-10 calibration")]
    assert by[("levels", "ecc-63-10 self-calibrated")] - oracle < 0.25 * (cal - oracle)


def test_decoding_methods_with_the_defaults():
    """The paper's decode_quant claims with the library defaults (wrong or unpublished = error):
    hard > soft; the best of list / median cuts soft's error >= 2x, list alone >= 1.5x, where soft
    errs on a few percent."""
    cfg = SweepConfig(width=64, height=48, seeds=(0,), ratios=(0.63, 2.0), experiments=("decode_quant",))
    rows = run_sweep(cfg, edge_decoder(), progress=False)
    by = {(r.series, r.x): r for r in rows}
    assert {r.extra["validity"] for r in rows if r.series != "hard"} == {"error"}
    for x in (0.63, 2.0):
        assert by[("hard", x)].error_rate > by[("soft", x)].error_rate
    soft = by[("soft", 0.63)].error_rate
    assert 0.02 < soft < 0.3  # the regime of the claim (here 6.3 %; list 3.2 %, median 1.6 %)
    # the best spatial method halves soft's error (issue 11); the order prior alone cuts it by
    # about 1.95x here, just short of the paper's 2x at this point (docs/results/eval shows the
    # claim over the sweep)
    assert min(by[(m, 0.63)].error_rate for m in ("list", "median")) <= soft / 2
    assert by[("list", 0.63)].error_rate <= soft / 1.5
    # the soft rule publishes almost nothing wrong: its error is pixels it withholds
    assert by[("soft", 0.63)].wrong_rate < 0.1 * soft


def test_sweep_config_rejects_bad_values():
    with pytest.raises(ValueError, match="unknown experiment"):
        SweepConfig(experiments=("soft_quant", "nope"))
    with pytest.raises(ValueError, match="levels"):
        SweepConfig(levels="oracle")
    with pytest.raises(ValueError, match="levels"):
        SweepConfig(levels="refined")  # the old refit-twice source is no longer a sweep setting
