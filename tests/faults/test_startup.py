"""Fault suite, start-up: one clear line and exit code 2, never a traceback; recordings never
destroyed (existing --record, --replay X --record X, --recover --out a link to the input)."""

from __future__ import annotations

import os
import shutil

import pytest

import faults_lifecycle as F
from _service_helpers import DATA

COMMITTED = DATA / "sim-small.mcap"


class Result:
    def __init__(self, rc, err):
        self.returncode, self.stderr = rc, err


def run_main(args, capsys):
    """``edge`` in this process (the same code path as the console script, without its start-up cost)."""
    from edge.cli import main

    capsys.readouterr()
    rc = main([str(a) for a in args])
    return Result(rc, capsys.readouterr().err)


@pytest.fixture(scope="module")
def held_port():
    s = F.hold_port()
    yield F.HELD_PORT[0]
    s.close()


def _cases(tmp_path_factory):
    return F.startup_error_cases(tmp_path_factory.mktemp("startup"))


@pytest.mark.parametrize("index", range(12))
def test_startup_error_is_one_line_exit_2(index, tmp_path_factory, held_port, capsys):
    """Before the fix: zenoh.ZError / RuntimeError / OSError tracebacks (exit 1), a hang with --sensor oak."""
    cases = _cases(tmp_path_factory)
    name, args, expect = cases[index]
    r = run_main(args, capsys)
    assert F.startup_error_ok(r, expect), f"{name}: rc {r.returncode}\n{r.stderr}"


def test_startup_case_list_is_complete(tmp_path_factory):
    assert len(_cases(tmp_path_factory)) == 12


def test_failed_startup_leaves_an_existing_recording_untouched(tmp_path, held_port, capsys):
    """Before the fix --record truncated the old file even when start-up then failed (port taken)."""
    old = tmp_path / "old.mcap"
    shutil.copy(COMMITTED, old)
    before = old.read_bytes()
    r = run_main(["run", "--profile", str(F.TEST_PROFILE), "--stacks", "1", "--record", str(old),
                  "--overwrite", "--listen", f"tcp/127.0.0.1:{held_port}"], capsys)
    assert F.startup_error_ok(r, "already in use"), r.stderr
    assert old.read_bytes() == before


def test_replay_into_its_own_input_is_refused(tmp_path, capsys):
    """Before the fix --replay X --record X wiped the input and exited 0."""
    src = tmp_path / "in.mcap"
    shutil.copy(COMMITTED, src)
    link = tmp_path / "link.mcap"
    os.symlink(src, link)
    before = src.read_bytes()
    for target in (src, link):
        r = run_main(["run", "--sensor", "replay", "--replay", str(src), "--record", str(target),
                      "--overwrite", "--no-zenoh"], capsys)
        assert F.startup_error_ok(r, "is an input of this command"), r.stderr
    assert src.read_bytes() == before


@pytest.mark.parametrize("kind", ["same", "symlink", "hardlink"])
def test_recover_out_that_is_the_input_is_refused(tmp_path, kind, capsys):
    """Before the fix --recover --out a symlink or hard link to the input truncated it to 300 B."""
    from edge.cli import main

    src = tmp_path / "in.mcap"
    shutil.copy(COMMITTED, src)
    before = src.read_bytes()
    out = src if kind == "same" else tmp_path / "out.mcap"
    if kind == "symlink":
        os.symlink(src, out)
    elif kind == "hardlink":
        os.link(src, out)
    rc = main(["replay", str(src), "--recover", "--out", str(out)])
    err = capsys.readouterr().err
    assert rc == 2 and "is an input of this command" in err and "Traceback" not in err, err
    assert src.read_bytes() == before


def test_connect_to_nobody_runs_with_a_warning(tmp_path, capsys):
    """Before the fix a --connect endpoint nobody listens on ran without a word."""
    port = F.free_port()
    r = run_main(["run", "--profile", str(F.TEST_PROFILE), "--stacks", "1", "--max-speed", "--quiet",
                  "--listen", f"tcp/127.0.0.1:{F.free_port()}", "--connect", f"tcp/127.0.0.1:{port}"], capsys)
    assert r.returncode == 0, r.stderr
    assert f"warning: nobody answers on zenoh connect endpoint tcp/127.0.0.1:{port}" in r.stderr


def test_help_says_what_happens_to_an_existing_file():
    from edge.cli import build_parser

    sub = build_parser()._subparsers._group_actions[0].choices["run"]
    text = sub.format_help()
    assert "--overwrite" in text and "existing file is refused" in " ".join(text.split())
