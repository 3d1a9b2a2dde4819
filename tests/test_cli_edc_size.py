"""`edge edc run` and `edge edc eval` check the camera size with one rule (`edge.eval.edc.check_gi_size`):
the scattering scenes need 6x5 pixels (their region generator), every other scene 2x2.  `edc run`
used to accept 5x5 on the scattering scene and fail inside numpy ("high <= 0"), while `edc eval`
refused anything under an arbitrary 8x8."""

from __future__ import annotations

import pytest

import edge.eval.edc
import edge.sim.scenes
from edge.cli import main
from edge.eval.edc import GI_SCENES, check_gi_size, gi_min_size
from edge.sim import make_scene

SCATTERING = [s for s in GI_SCENES if gi_min_size(s) == (6, 5)]


def _error(capsys, *argv: str) -> str:
    rc = main([str(a) for a in argv])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2, (argv, err)
    assert len(err) == 1 and "Traceback" not in err[0], err
    return err[0]


def test_the_size_rule_is_the_scene_generators_own(monkeypatch):
    """6x5 builds every scattering scene; one column or one row less is refused by `make_scene`
    with its own message, and without the rule fails inside the generator (so the rule is neither
    stricter nor looser than the generator)."""
    assert SCATTERING == ["scattering", "scatter-s1.5", "scatter-s4", "scatter-s10"]
    for w, h in ((6, 5), (7, 9)):
        make_scene("scattering", w, h)
    for w, h in ((5, 5), (6, 4)):
        with pytest.raises(ValueError, match=f"scene 'scattering' needs at least 6x5 pixels, got {w}x{h}"):
            make_scene("scattering", w, h)
    monkeypatch.setattr(edge.sim.scenes, "_MIN_SIZE", {})
    for w, h in ((5, 5), (6, 4)):
        with pytest.raises(ValueError, match="high <= 0"):  # numpy's message, naming nothing
            make_scene("scattering", w, h)
    assert {gi_min_size(s) for s in GI_SCENES if s not in SCATTERING} == {(2, 2)}
    with pytest.raises(ValueError, match="camera 1x1 is too small: GI scene bowl needs at least 2x2 pixels"):
        check_gi_size("bowl", 1, 1)


@pytest.mark.parametrize("size", ["5x5", "6x4"])
def test_both_actions_refuse_a_camera_too_small_with_one_message(capsys, tmp_path, size):
    w, h = size.split("x")
    run = _error(capsys, "edc", "run", "--scene", "scatter-s4", "--size", size)
    assert run == f"edge edc run: error: --size: camera {w}x{h} is too small: GI scene scatter-s4 needs at least 6x5 pixels"
    out = tmp_path / "edc"
    ev = _error(capsys, "edc", "eval", "--size", size, "--out", out)
    assert ev == (f"edge edc eval: error: --size: camera {w}x{h} is too small: GI scenes {', '.join(SCATTERING)} "
                  "need at least 6x5 pixels")
    assert not out.exists()  # refused before the output folder is made


def test_run_refuses_under_2x2_on_other_scenes(capsys):
    assert _error(capsys, "edc", "run", "--size", "1x4") == (
        "edge edc run: error: --size: camera 1x4 is too small: GI scene v-groove needs at least 2x2 pixels")


@pytest.mark.parametrize("scene, size, pixels", [("v-groove", "2x2", 4), ("scattering", "6x5", 30)])
def test_run_takes_the_smallest_valid_size(capsys, scene, size, pixels):
    assert main(["edc", "run", "--scene", scene, "--size", size, "--rounds", "1"]) == 0
    out = capsys.readouterr().out
    assert f"on {scene}: 1 rounds" in out and f"lit pixels {pixels}:" in out


def test_eval_takes_the_smallest_valid_size(capsys, tmp_path):
    out = tmp_path / "edc"
    assert main(["edc", "eval", "--size", "6x5", "--out", str(out)]) == 0
    assert {p.name for p in out.iterdir()} == {"README.md", "roc.png", "loop.png"}
    assert "camera 6x5" in (out / "README.md").read_text()


def test_run_report_checks_every_scene_before_the_work(tmp_path, monkeypatch):
    """A too-small camera failed at the first scattering scene, after the scenes before it had run."""
    def never(*_a, **_k):
        raise AssertionError("the work started before the size was checked")

    monkeypatch.setattr(edge.eval.edc, "error_map_roc", never)
    with pytest.raises(ValueError, match="camera 8x4 is too small: GI scenes scattering, "):
        edge.eval.edc.run_report(tmp_path / "r", width=8, height=4, progress=False)
    assert not (tmp_path / "r").exists()
