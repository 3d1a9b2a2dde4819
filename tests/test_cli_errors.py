"""The command line on bad input and a hostile environment: one line naming the problem, exit code
2, no traceback, and nothing already on disk replaced (in-process `edge.cli.main`)."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from edge.cli import main, user_error

DATA = Path(__file__).parent / "data"
PROFILE = str(DATA / "profiles" / "test-small.toml")


def _fails(capsys, *argv: str, expect: str) -> str:
    rc = main([str(a) for a in argv])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2, (argv, err)
    assert err and "Traceback" not in "\n".join(err), err
    assert expect in err[-1], (expect, err[-1])
    return err[-1]


@pytest.mark.parametrize("name, expect", [
    ("rm-2-10", "2**56 codewords, more than the 65536"),  # was a 512 PiB allocation
    ("hamming-31-26", "2**26 codewords"),
    ("bch-63-30", "2**30 codewords"),
    ("gray-99999999999999", "codewords, more than"),
    ("nary8-7", "2**21 codewords"),
])
def test_codes_too_large_are_refused_by_name(capsys, name, expect):
    _fails(capsys, "codes", "show", name, expect=expect)


def test_code_commands_take_their_own_defaults(capsys):
    assert main(["codes", "show", "poisson-20-8"]) == 0  # its own column order (was refused for --order gray)
    assert "poisson-20-8" in capsys.readouterr().out
    _fails(capsys, "codes", "table", "--k", "0", expect="--k: expected a number of information bits >= 1")


def test_code_search_options_are_named_when_wrong(capsys):
    """--widths 5-3 searched nothing and failed with "max() arg is an empty sequence"."""
    _fails(capsys, "codes", "edc-search", "--widths", "5-3", expect="--widths expects 'LO-HI' (LO <= HI)")
    _fails(capsys, "codes", "edc-search", "--max-stripe", "0", expect="--max-stripe: expected")
    _fails(capsys, "codes", "table", "--n-max", "0", expect="--n-max: expected 12..128")
    assert main(["codes", "table", "--k", "6", "--n-max", "200"]) == 2
    err = capsys.readouterr().err
    assert "--n-max: expected 6..128" in err and "code table:" not in err  # refused before the progress bar


def test_recordings_are_not_replaced_without_overwrite(capsys, tmp_path):
    rec = tmp_path / "a.mcap"
    shutil.copy(DATA / "sim-small.mcap", rec)
    before = rec.read_bytes()
    _fails(capsys, "sim", "record", rec, "--stacks", "1", "--profile", PROFILE, expect="already exists; pass --overwrite")
    profile_copy = tmp_path / "p.toml"
    shutil.copy(PROFILE, profile_copy)
    _fails(capsys, "sim", "record", profile_copy, "--stacks", "1", "--profile", profile_copy,
           expect="is an input of this command")
    other = tmp_path / "b.mcap"
    shutil.copy(DATA / "sim-small.mcap", other)
    _fails(capsys, "replay", rec, "--recover", "--out", other, expect="--out")
    assert rec.read_bytes() == before and other.read_bytes() == before
    assert profile_copy.read_text() == Path(PROFILE).read_text()
    _fails(capsys, "sim", "record", tmp_path, "--stacks", "1", "--profile", PROFILE, expect="is a folder; expected a file name")
    # a file where the folder should be was named a missing folder
    _fails(capsys, "sim", "record", rec / "sub" / "x.mcap", "--stacks", "1", "--profile", PROFILE,
           expect=f"{rec} is a file, not a folder")
    assert rec.read_bytes() == before
    _fails(capsys, "replay", rec, other, "--ply", tmp_path / "ply", expect="--ply replays one recording")


def test_bad_numbers_and_sizes(capsys, tmp_path):
    _fails(capsys, "source", "event-demo", "--size", "64x48", "--periods", "0", expect="periods: expected >= 1")
    _fails(capsys, "source", "event-demo", "--size", "64x48", "--flicker", "nan", expect="flicker_hz")
    _fails(capsys, "edc", "eval", "--size", "4x4", "--out", tmp_path / "edc", expect="at least 6x5")
    _fails(capsys, "edc", "run", "--size", "100000x100000", expect="at most 16384x16384")
    _fails(capsys, "edc", "run", "--size", "32x24", "--seed", "-1", expect="--seed must be >= 0")  # numpy's text
    _fails(capsys, "edc", "eval", "--size", "8x8", "--seed", "-1", "--out", tmp_path / "e", expect="--seed must be >= 0")
    _fails(capsys, "edc", "run", "--size", "32x24", "--rounds", "0", expect="--rounds must be >= 1")
    assert not (tmp_path / "e").exists()


def test_user_error_covers_the_environment():
    """What `main` reports as one line instead of a traceback: OSErrors with their path, memory,
    zenoh (its Rust source locations stripped), OpenCV; anything else is a bug and is raised."""
    assert user_error(IsADirectoryError(21, "Is a directory", "/x")) == "Is a directory: /x"
    assert user_error(OSError(28, "No space left on device", "/dev/full")) == "No space left on device: /dev/full"
    assert "not enough memory" in user_error(MemoryError("Unable to allocate 8 GiB"))
    assert user_error(ValueError("bad")) == "bad"
    zenoh = pytest.importorskip("zenoh")
    text = user_error(zenoh.ZError("Address already in use at /root/.cargo/x/src/a.rs:12."))
    assert text.startswith("cannot open the zenoh session") and ".rs:" not in text and "already listens" in text
    cv2 = pytest.importorskip("cv2")
    assert user_error(cv2.error("could not find a writer\nmore")) == "could not find a writer"
    assert user_error(KeyError("x")) is None and user_error(IndexError("x")) is None


def test_a_directory_or_a_file_in_the_wrong_place_is_named_as_such(capsys, tmp_path):
    _fails(capsys, "profiles", "show", tmp_path, expect="is a folder; expected a TOML file")
    assert main(["profiles", "check", str(tmp_path)]) == 1  # the checker reports per file and goes on
    assert "is a folder; expected a TOML file" in capsys.readouterr().out
    _fails(capsys, "decode-images", DATA / "sim-small.mcap", expect="is a file; expected the folder")


def test_a_group_command_names_its_action(capsys):
    assert _fails(capsys, "codes", "show", "rm-2-10", expect="codewords").startswith("edge codes show: error:")


def test_eval_outputs_that_cannot_be_written_fail_before_the_work(capsys, tmp_path, monkeypatch):
    """`edge eval sweep` ran the whole sweep (hours without --quick) and only then failed to write
    --out; `edge edc eval` likewise named only the OSError."""
    import edge.eval.edc
    import edge.eval.sweep

    def never(*_a, **_k):
        raise AssertionError("the work started before --out was checked")

    monkeypatch.setattr(edge.eval.sweep, "run_sweep", never)
    monkeypatch.setattr(edge.eval.edc, "make_gi_scene", never)
    blocker = tmp_path / "file"
    blocker.write_text("x")
    _fails(capsys, "eval", "sweep", "--quick", "--out", blocker / "out", expect="--out")
    _fails(capsys, "eval", "sweep", "--quick", "--out", blocker, expect="is a file; expected a folder")
    _fails(capsys, "edc", "eval", "--size", "8x8", "--out", blocker / "out", expect=f"{blocker} is a file, not a folder")
    assert blocker.read_text() == "x"


def test_run_refuses_a_replay_file_the_sensor_would_not_read(capsys, tmp_path):
    """`edge run --replay FILE` without --sensor replay ran the simulator and exited 0, as if the
    recording had been replayed."""
    rec = DATA / "sim-small.mcap"
    _fails(capsys, "run", "--replay", rec, "--profile", PROFILE, "--no-zenoh", "--stacks", "1",
           expect="add --sensor replay")
    _fails(capsys, "run", "--sensor", "sim", "--replay", rec, "--profile", PROFILE, "--no-zenoh", "--stacks", "1",
           "--record", tmp_path / "out.mcap", expect="the sensor is 'sim'")
    assert not (tmp_path / "out.mcap").exists()


def test_sim_record_checks_first_stack_before_creating_the_file(capsys, tmp_path):
    """--first-stack -1 created OUT.mcap, then failed with numpy's "expected non-negative integer";
    the empty recording left behind blocked the next try ("already exists")."""
    out = tmp_path / "o.mcap"
    _fails(capsys, "sim", "record", out, "--stacks", "1", "--profile", PROFILE, "--first-stack", "-1",
           expect="--first-stack must be >= 0, got -1")
    assert not out.exists()


def test_source_codes_options_are_checked(capsys):
    """`edge source codes`: CODES with --family (or --table with --room-family) reported one and
    ignored the other; --lengths 4,x was int()'s message; a length outside 2..16 or --max-devices
    below 2 printed a table without that column / with no rows and exit 0."""
    _fails(capsys, "source", "codes", "1101", "--family", "2", "4", expect="CODES and --family: give one of")
    _fails(capsys, "source", "codes", "--table", "--room-family", "3", "6", expect="--table and --room-family")
    _fails(capsys, "source", "codes", "--table", "--lengths", "4,x", expect="--lengths expects a comma list")
    _fails(capsys, "source", "codes", "--table", "--lengths", "4,99", expect="--lengths: room families have 2 <= L")
    _fails(capsys, "source", "codes", "--table", "--lengths", "4", "--max-devices", "1", expect="--max-devices")
    # the room options were ignored without a word outside --table / --room-family
    _fails(capsys, "source", "codes", "1101", "--power-ratio", "2", expect="--power-ratio: options of --table")
    _fails(capsys, "source", "codes", "--family", "2", "4", "--stream", "periodic", "--lengths", "4",
           expect="--stream / --lengths: options of --table")
    _fails(capsys, "source", "codes", "--room-family", "2", "4", "--max-devices", "3", expect="options of --table, not")
    assert main(["source", "codes", "--room-family", "2", "6", "--power-ratio", "0.5"]) == 0
    assert "each foreign device <= 0.5 x own" in capsys.readouterr().out


def test_subscribe_and_router_check_their_arguments_first(capsys, tmp_path, monkeypatch):
    """`edge subscribe --png/--ply` found an unwritable path only after the whole subscription
    (the depth received was lost), `--all` ignored --ply, and a malformed --connect endpoint or a
    router port in use was zenoh's JSON5 / Rust-located text."""
    import socket

    import edge.io.zenoh

    def never(*_a, **_k):
        raise AssertionError("subscribed before the arguments were checked")

    monkeypatch.setattr(edge.io.zenoh, "DepthSubscriber", never)
    blocker = tmp_path / "file"
    blocker.write_text("x")
    _fails(capsys, "subscribe", "--png", blocker / "d.png", expect="--png")
    _fails(capsys, "subscribe", "--png", tmp_path / "depth", expect="expected an image file name")
    _fails(capsys, "subscribe", "--ply", tmp_path, expect="--ply")
    _fails(capsys, "subscribe", "--all", "--ply", tmp_path / "c.ply", expect="--ply")
    _fails(capsys, "subscribe", "--connect", "garbage", expect="expected <protocol>/<address>")
    _fails(capsys, "router", "--listen", "garbage", "--seconds", "1", expect="expected <protocol>/<address>")
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        line = _fails(capsys, "router", "--listen", f"tcp/127.0.0.1:{port}", "--seconds", "1",
                      expect="already in use")
    assert ".rs:" not in line


def test_replay_report_never_replaces_a_recording(capsys, tmp_path, monkeypatch):
    """`edge replay a.mcap --report a.mcap` (or --report naming another recording) replaced the
    recording with the JSON report; a --report that is a folder failed only after every replay."""
    import edge.io.replay_many

    recs = tmp_path / "recs"
    recs.mkdir()
    for name in ("a.mcap", "b.mcap"):
        shutil.copy(DATA / "sim-small.mcap", recs / name)
    before = (DATA / "sim-small.mcap").read_bytes()
    _fails(capsys, "replay", recs / "a.mcap", "--report", recs / "a.mcap", expect="is a recording")
    _fails(capsys, "replay", recs, "--report", recs / "b.mcap", expect="is a recording")
    (tmp_path / "link.json").symlink_to(recs / "b.mcap")
    _fails(capsys, "replay", recs / "a.mcap", "--report", tmp_path / "link.json", expect="is a recording")
    assert all((recs / n).read_bytes() == before for n in ("a.mcap", "b.mcap"))

    def never(*_a, **_k):
        raise AssertionError("replayed before --report was checked")

    monkeypatch.setattr(edge.io.replay_many, "replay_serial", never)
    _fails(capsys, "replay", recs, "--report", tmp_path, expect="--report")


def test_decode_images_never_writes_over_its_inputs(capsys, tmp_path):
    """`edge decode-images DIR --column-map DIR/white.png --out DIR/pattern_00.png` replaced the
    capture's own images with its outputs (the capture no longer decoded); an output that could not
    be written failed only after the decode."""
    cap = tmp_path / "cap"
    assert main(["patterns", "write", "--code", "gray-8", "--size", "64x16", str(cap)]) == 0
    capsys.readouterr()
    before = {p.name: p.read_bytes() for p in cap.iterdir()}
    _fails(capsys, "decode-images", cap, "--column-map", cap / "white.png", expect="is an input of this command")
    _fails(capsys, "decode-images", cap, "--out", cap / "pattern_00.png", expect="is an input of this command")
    _fails(capsys, "decode-images", cap, "--out", cap / "col.png", "--confidence-out", cap / "manifest.json",
           expect="--confidence-out")
    (cap / "c.json").symlink_to(cap / "black.png")
    _fails(capsys, "decode-images", cap, "--ply", cap / "c.json", expect="is an input of this command")
    (cap / "c.json").unlink()
    assert {p.name: p.read_bytes() for p in cap.iterdir()} == before
    assert main(["decode-images", str(cap), "--out", str(tmp_path / "missing" / "col.png")]) == 2
    captured = capsys.readouterr()
    assert "does not exist" in captured.err and "decoded" not in captured.out  # refused before the decode


def test_replay_of_one_recording_shows_progress(capsys, monkeypatch):
    """`edge replay FILE` printed nothing until the whole recording was decoded (minutes for a long
    one); it now drives a progress bar over the recorded depth maps (shown on a terminal)."""
    import tqdm

    bars = []

    class Bar:
        def __init__(self, total=None, **kwargs):
            self.total, self.n, self.kwargs = total, 0, kwargs
            bars.append(self)

        def update(self, n=1):
            self.n += n

        def close(self):
            self.closed = True

    monkeypatch.setattr(tqdm, "tqdm", Bar)
    assert main(["replay", str(DATA / "sim-small.mcap")]) == 0
    assert "bit for bit" in capsys.readouterr().out
    assert len(bars) == 1 and bars[0].total == 3 and bars[0].n == 3 and bars[0].closed


def test_progress_bars_only_on_a_terminal_and_replay_usage(capsys, tmp_path):
    """`edge sim record`'s bar wrote tqdm's carriage-return lines into a redirected stderr (a log
    file, CI); like the replay bar it now shows only on a terminal.  `edge replay` with no file
    named its two positionals 'FILE, FILE' as required."""
    import subprocess
    import sys

    out = tmp_path / "rec.mcap"
    r = subprocess.run([sys.executable, "-m", "edge.cli", "sim", "record", str(out), "--stacks", "2",
                        "--profile", PROFILE], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0 and out.exists(), r.stderr
    assert "\r" not in r.stderr and "stack/s" not in r.stderr and "it/s" not in r.stderr
    with pytest.raises(SystemExit) as exc:
        main(["replay"])
    assert exc.value.code == 2
    assert capsys.readouterr().err.strip().endswith("the following arguments are required: FILE")
