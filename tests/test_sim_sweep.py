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


def test_levels_experiment_pairs_noise_and_oracle_levels_help():
    decoder = edge_decoder()
    cfg = SweepConfig(width=64, height=48, seeds=(0,), ratios=(0.4,), experiments=("levels", "soft_quant"))
    rows = run_sweep(cfg, decoder, progress=False)
    by = {(r.experiment, r.series): r for r in rows}
    # same capture, same noise: the levels experiment's "refined" row equals soft_quant's row
    assert by[("levels", "ecc-22-10 refined")].error_rate == by[("soft_quant", "ecc-22-10 s=0.04")].error_rate
    for name in ("gray-10", "ecc-63-10"):
        cal = by[("levels", f"{name} calibration")].error_rate
        assert by[("levels", f"{name} oracle")].error_rate <= cal
        assert by[("levels", f"{name} refined")].error_rate <= cal


def test_sweep_config_rejects_bad_values():
    with pytest.raises(ValueError, match="unknown experiment"):
        SweepConfig(experiments=("soft_quant", "nope"))
    with pytest.raises(ValueError, match="levels"):
        SweepConfig(levels="oracle")
