"""The evaluations run what the service runs: every decoder configuration they evaluate is a profile."""

from __future__ import annotations

import pytest

from edge.decode.settings import DecodeSettings, from_profile
from edge.eval.edc import SINGLE_PASS
from edge.eval.report import markdown_table, profile_sections
from edge.eval.sweep import EXPERIMENTS, SweepConfig, configurations
from edge.profiles import load_profile
from edge.profiles.files import apply_update


def _evaluated() -> list[DecodeSettings]:
    out = [SINGLE_PASS]
    for levels in ("refined", "calibration"):
        out += configurations(SweepConfig(levels=levels))
    return list(dict.fromkeys(out))


def test_every_evaluated_configuration_round_trips_through_a_profile():
    configs = _evaluated()
    # the sweep's grid: 4 methods x the level sources, the noise of each camera model
    assert {c.method for c in configs} == {"hard", "soft", "list", "median"}
    assert {c.levels for c in configs} <= {"auto", "calibration", "refit"}
    assert {c.sigma_s for c in configs} >= {1e-4, 0.015, 0.04}
    base = load_profile("sim-dlp")
    for settings in configs:
        sections = profile_sections(settings)
        assert set(sections) == {"decoder", "camera"}
        profile = apply_update(base, sections, source="evaluated configuration")
        assert profile.decoder.levels == settings.levels
        assert from_profile(profile) == settings, settings


def test_sweep_levels_map_onto_settings():
    by_levels = {lv: configurations(SweepConfig(levels=lv, experiments=("decode_quant",))) for lv in ("refined", "calibration")}
    assert {c.levels for c in by_levels["refined"]} == {"refit"}
    assert {c.levels for c in by_levels["calibration"]} == {"calibration"}
    assert all(c.min_contrast == 0.0 and c.min_confidence == 0.0 for c in by_levels["refined"])
    # the levels experiment decodes its oracle rows with the calibration levels (noise-free white / black)
    lv = configurations(SweepConfig(experiments=("levels",)))
    assert {c.levels for c in lv} == {"calibration", "refit"}
    assert len(configurations(SweepConfig(experiments=EXPERIMENTS))) == len(configurations(SweepConfig()))


def test_markdown_table_shape():
    assert markdown_table(["a", "b"], [[1, ""], ["x", 2.5]]) == ["| a | b |", "|---|---|", "| 1 |  |", "| x | 2.5 |"]


def test_profile_rejects_a_configuration_it_cannot_run():
    bad = profile_sections(SINGLE_PASS)
    bad["decoder"]["levels"] = "oracle"
    with pytest.raises(ValueError, match="levels"):
        apply_update(load_profile("sim-dlp"), bad)


def test_curtain_demo_cli_runs_the_eval_package(capsys):
    from edge.cli import main

    assert main(["source", "curtain-demo", "--size", "48x32"]) == 0
    rows = [line.split() for line in capsys.readouterr().out.splitlines()[1:]]
    assert [r[0] for r in rows] == ["1/1", "1100/0101", "1100/0101", "1100/0101", "001011/001101/011111"]
    assert float(rows[0][-2]) > 0.1  # uncoded: the second laser's false curtain is detected
    assert all(float(r[-2]) == 0.0 and float(r[-1]) < 0.01 for r in rows[1:])  # coded: none, none missed
