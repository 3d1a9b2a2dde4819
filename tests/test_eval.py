"""The evaluations run what the service runs: every decoder configuration they evaluate is a profile."""

from __future__ import annotations

import numpy as np
import pytest

from edge.decode.settings import DEFAULT_SETTINGS, DecodeSettings, from_profile
from edge.eval.edc import SINGLE_PASS
from edge.eval.report import calibration_verdict, markdown_table, poisson_interval, profile_sections
from edge.eval.sweep import EXPERIMENTS, SweepConfig, configurations
from edge.profiles import load_profile
from edge.profiles.files import apply_update


def _evaluated() -> list[DecodeSettings]:
    out = [SINGLE_PASS]
    for levels in ("auto", "calibration"):
        out += configurations(SweepConfig(levels=levels))
    return list(dict.fromkeys(out))


def test_every_evaluated_configuration_round_trips_through_a_profile():
    configs = _evaluated()
    # the sweep's grid: 4 methods x the level sources, nothing else changed from the library defaults
    assert {c.method for c in configs} == {"hard", "soft", "list", "median"}
    assert {c.levels for c in configs} == {"auto", "calibration"}
    for c in configs:
        assert c == DEFAULT_SETTINGS.replace(method=c.method, levels=c.levels), c
    base = load_profile("sim-dlp")
    for settings in configs:
        sections = profile_sections(settings)
        assert set(sections) == {"decoder", "camera"}
        profile = apply_update(base, sections, source="evaluated configuration")
        assert profile.decoder.levels == settings.levels
        assert from_profile(profile) == settings, settings


def test_sweep_runs_the_library_defaults():
    by_levels = {lv: configurations(SweepConfig(levels=lv, experiments=("decode_quant",))) for lv in ("auto", "calibration")}
    assert by_levels["auto"] == [DEFAULT_SETTINGS.replace(method=m) for m in ("hard", "soft", "list", "median")]
    assert {c.levels for c in by_levels["calibration"]} == {"calibration"}
    # soft / list / median decode under the self-calibrating error rule, hard under the confidence rule
    assert [c.rule(False) for c in by_levels["auto"]] == ["confidence", "error", "error", "error"]
    # the levels experiment: the default self-calibration, the calibration frames, and the oracle
    # (noise-free white / black decoded with the calibration levels)
    lv = configurations(SweepConfig(experiments=("levels",)))
    assert lv == [DEFAULT_SETTINGS, DEFAULT_SETTINGS.replace(levels="calibration")]
    assert len(configurations(SweepConfig(experiments=EXPERIMENTS))) == len(configurations(SweepConfig()))


def test_edc_single_pass_is_the_defaults_and_reads_every_pixel():
    """`edge edc eval` decodes with the defaults (method hard); the column it scores, the top-1
    candidate (the nearest codeword), does not depend on the validity thresholds."""
    from edge.codes import get_code
    from edge.decode import decode
    from edge.sim import CameraModel, capture_code, make_scene

    assert SINGLE_PASS == DEFAULT_SETTINGS.replace(method="hard")
    code = get_code("xor02-10+crc5")
    cap = capture_code(make_scene("flying", 64, 48, seed=0), code, CameraModel(sigma_s=0.04, ambient=0.4,
                                                                                 projector=0.1), rng=1)
    dec = decode(cap.frames, cap.white, cap.black, code, settings=SINGLE_PASS)
    bare = decode(cap.frames, cap.white, cap.black, code, settings=SINGLE_PASS, min_contrast=0.0,
                  min_confidence=0.0, spatial_check=False)
    assert 0 < dec.valid.sum() < bare.valid.sum()  # the default thresholds reject pixels ...
    assert np.array_equal(dec.candidates[..., 0], bare.candidates[..., 0])  # ... but not the columns scored


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


def test_poisson_interval_matches_closed_forms():
    """Garwood's interval where it has a closed form: k = 0 (upper -ln(tail)), k = 1 (lower
    -ln(1 - tail); upper solves e**-mu (1 + mu) = tail), and brackets of the count itself."""
    from math import exp, log

    low, high = poisson_interval(0, 0.99)
    assert low == 0.0 and abs(high + log(0.005)) < 1e-9
    low, high = poisson_interval(1, 0.99)
    assert abs(low + log(0.995)) < 1e-9
    assert abs(exp(-high) * (1.0 + high) - 0.005) < 1e-12
    for k in (3, 15, 100):
        low, high = poisson_interval(k, 0.95)
        assert low < k < high
        assert poisson_interval(k, 0.99)[0] < low and poisson_interval(k, 0.99)[1] > high


def test_calibration_verdict():
    """Within 2x; outside it but not ruled out by a small count; ruled out by a large one."""
    assert calibration_verdict(10.0, 19) == "within"
    assert calibration_verdict(10.0, 5) == "within"
    assert calibration_verdict(3.1, 7) == "consistent"  # 2.3x on 7 errors: 99 % interval 2.0-16.8
    assert calibration_verdict(2.0, 0) == "consistent"
    assert calibration_verdict(100.0, 250) == "off"
    assert calibration_verdict(100.0, 30) == "off"
