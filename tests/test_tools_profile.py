"""tools/profile_decode.py on a small capture: every table row is printed and the decoder's stage
functions are the originals again afterwards (the tool wraps them only while it times)."""

from __future__ import annotations


import edge.decode.decoder as decoder
import edge.decode.posterior as posterior

from _tools import load_tool


def _tool():
    return load_tool("profile_decode")


def test_profile_decode_prints_every_row_and_restores_the_stages(capsys):
    tool = _tool()
    before = {name: getattr(decoder, name) for name in tool.STAGES}
    flips, tail_pass = posterior._flips, posterior._tail_pass
    assert tool.main(["--repeats", "1", "--height", "48", "--width", "64"]) == 0
    out = capsys.readouterr().out
    for row in ("| easy |", "| easy, band [0, 128] |", "| hard |", "| hard, band [", "| as is |",
                "| no tail anywhere |", "the tail is due on"):
        assert row in out, row
    if tool.REAL.is_dir():  # the real capture's tables, where the data is beside the repository
        assert "| whole | search_candidates | confidence_fit |" in out
        assert "The search (path lanes):" in out and "ties at cost 0 resolved directly" in out
        assert "| pattern only (defaults) |" in out and '| pattern + inverse, validity="error" |' in out
    assert all(getattr(decoder, name) is fn for name, fn in before.items())
    assert posterior._flips is flips and posterior._tail_pass is tail_pass
