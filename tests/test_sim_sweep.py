"""Evaluation sweep plumbing: message re-ordering, a tiny sweep, the report files."""

from __future__ import annotations

import numpy as np
import pytest

from edge.codes import get_code
from edge.sim.sweep import SweepConfig, claims, edge_decoder, reorder, run_sweep, write_report


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
    try:
        decoder = edge_decoder()
    except ImportError:
        pytest.skip("edge.decode not available")
    cfg = SweepConfig(width=64, height=48, seeds=(0,), ratios=(0.05, 2.0), experiments=("soft_quant",))
    rows = run_sweep(cfg, decoder, progress=False)
    assert len(rows) == 2 * 4 * 2
    by = {(r.series, r.x): r.error_rate for r in rows}
    for ss in (0.015, 0.04):
        assert by[(f"gray-10 s={ss}", 2.0)] < by[(f"gray-10 s={ss}", 0.05)]
    assert all(0.0 <= r.error_rate <= 1.0 and r.pixels > 1000 for r in rows)
    path = write_report(rows, tmp_path, cfg, command="test", decoder_name="edge.decode", seconds=0.0)
    text = path.read_text()
    assert (tmp_path / "soft_quant.png").stat().st_size > 1000 and (tmp_path / "results.json").exists()
    assert "| gray-10 s=0.04 |" in text and "Paper claims" in text
    assert len(claims(rows)) == 4
