"""tools/eval_sgm_error.py: its counting helpers against hand-made cases, and one small run that
writes every row of its table."""

from __future__ import annotations

import numpy as np

from _tools import load_tool


def _tool():
    return load_tool("eval_sgm_error")


def test_published_errors_take_the_published_lit_pixels_and_one_row_of_slack():
    tool = _tool()
    column = np.array([[5, 6, 9, -1], [3, 3, 3, 3]], np.int32)
    valid = np.array([[True, True, True, False], [True, False, True, True]])
    error = np.array([[1e-5, 2e-3, 5e-4, 1.0], [1e-3, 0.5, 2e-5, 3e-3]], np.float32)
    truth = np.array([[5, 5, 5, 5], [3, 3, 1, 3]])
    lit = np.array([[True, True, True, True], [True, True, True, False]])
    p, wrong = tool.published_errors(column, valid, error, truth, lit)
    # published and lit: (0,0) (0,1) (0,2) (1,0) (1,2); off by more than one row: (0,2) and (1,2)
    np.testing.assert_allclose(p, np.array([1e-5, 2e-3, 5e-4, 1e-3, 2e-5], np.float32).astype(np.float64))
    assert wrong.tolist() == [False, False, True, False, True]


def test_bins_count_seen_against_the_sum_of_predictions():
    tool = _tool()
    p = np.array([1e-5, 5e-5, 2e-4, 5e-4, 5e-3, 5e-3])
    wrong = np.array([False, True, False, False, True, False])
    cells = tool.bins(p, wrong)
    assert cells[0].startswith("1 / 0.00 (2): ")  # seen 1 where 6e-5 was expected: off
    assert cells[0].endswith("off")
    assert cells[1] == "0 / 0.00 (2): consistent"
    assert cells[2] == "1 / 0.01 (2): consistent"
    assert tool.bins(np.zeros(0), np.zeros(0, bool)) == ["0 / 0.00 (0): -"] * 3


def test_from_added_state_is_the_propagated_column_and_not_one_of_the_top_three():
    tool = _tool()
    column = np.array([[7, 7, 7, -1]], np.int32)
    top3 = np.array([[[1, 2, 3], [7, 2, 3], [1, 2, 3], [1, 2, 3]]], np.int32)
    added = np.array([[7, 7, 8, -1]], np.int32)
    # (0,0): the added 7 is published and not in its top three; (0,1): 7 is its own best; (0,2):
    # the added state is 8, not the published 7; (0,3): nothing added, nothing published
    assert tool.from_added_state(column, top3, added).tolist() == [[True, False, False, False]]


def test_a_small_run_writes_every_row(tmp_path, capsys):
    tool = _tool()
    assert tool.main(["--size", "64x48", "--seeds", "0", "--ambient", "2", "--out", str(tmp_path)]) == 0
    text = (tmp_path / "README.md").read_text()
    rows = [line for line in text.splitlines() if line.startswith("| edge.sim |") or line.startswith("| plane-box-sphere |")]
    assert len(rows) == 2 * 2 * 2  # generators x codes x methods
    for row in rows:
        cells = [c.strip() for c in row.strip("|").split("|")]
        assert cells[3] in ("soft", "sgm") and 0.0 <= float(cells[4]) <= 1.0
        if cells[3] == "soft":  # the last three columns are sgm's
            assert cells[-1] == cells[-2] == cells[-3] == "-"
    assert "Command: `python tools/eval_sgm_error.py --size 64x48 --seeds 0 --ambient 2`" in text
