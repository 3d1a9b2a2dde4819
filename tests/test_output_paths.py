"""One check of an output location (`edge.io.paths.check_folder`): a file where a parent folder
should be is named the same way through every option.  `check_record_path` (recordings) named it at
any depth; `check_output_file` looked only at the immediate folder ("folder ... does not exist") and
`output_dir` reported the OSError ("cannot create the folder (Not a directory)")."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest

from edge.cli import main
from edge.io.mcap import RecordingReader, recover
from edge.io.paths import check_folder, file_in_the_way
from edge.io.recording import check_record_path

DATA = Path(__file__).parent / "data"
PROFILE = str(DATA / "profiles" / "test-small.toml")


@pytest.fixture
def blocker(tmp_path: Path) -> Path:
    """A file where a folder two levels above the output should be."""
    f = tmp_path / "blk"
    f.write_text("x")
    return f


def _one_error(capsys, argv: list) -> str:
    rc = main([str(a) for a in argv])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2, (argv, err)
    assert len(err) == 1 and "Traceback" not in err[0], err
    return err[0]


def _cases(blocker: Path) -> list[tuple[str, str, Path, list]]:
    """(command, option, output path, argv): recordings (check_record_path), files
    (check_output_file) and folders (output_dir), each two levels below ``blocker``."""
    rec = blocker / "a" / "b" / "x.mcap"
    folder = blocker / "a" / "b"
    other = blocker.parent / "other.mcap"
    shutil.copy(DATA / "sim-small.mcap", other)
    return [
        ("sim record", "OUT.mcap", rec, ["sim", "record", rec, "--stacks", "1", "--profile", PROFILE]),
        ("run", "--record", rec, ["run", "--record", rec, "--profile", PROFILE, "--no-zenoh", "--stacks", "1"]),
        ("replay", "--out", rec, ["replay", DATA / "sim-small.mcap", "--recover", "--out", rec]),
        ("replay", "--report", blocker / "a" / "b" / "r.json",
         ["replay", DATA / "sim-small.mcap", other, "--report", blocker / "a" / "b" / "r.json"]),
        ("eval sweep", "--out", folder, ["eval", "sweep", "--quick", "--out", folder]),
        ("edc eval", "--out", folder, ["edc", "eval", "--size", "8x8", "--out", folder]),
    ]


def test_a_file_two_levels_up_reads_the_same_through_every_option(capsys, blocker):
    reason = f"{blocker} is a file, not a folder"
    for command, option, path, argv in _cases(blocker):
        assert _one_error(capsys, argv) == f"edge {command}: error: {option} {path}: {reason}"
    picture = blocker / "a" / "b" / "v.png"  # decode-images' outputs read the same
    line = _one_error(capsys, ["decode-images", DATA, "--depth-picture", picture])
    assert line == f"edge decode-images: error: --depth-picture {picture}: {reason}"
    assert blocker.read_text() == "x" and sorted(p.name for p in blocker.parent.iterdir()) == ["blk", "other.mcap"]


def test_check_folder_names_the_file_at_any_depth(tmp_path, blocker):
    for depth in range(3):
        folder = Path(blocker, *["d"] * depth)
        assert file_in_the_way(folder) == blocker
        with pytest.raises(ValueError, match=f"^--x {folder}: {blocker} is a file, not a folder$"):
            check_folder(folder, option="--x")
        with pytest.raises(ValueError, match=f"^--x out.png: {blocker} is a file, not a folder$"):
            check_folder(folder, option="--x", path="out.png", missing_ok=True)


def test_check_folder_missing_and_present(tmp_path):
    missing = tmp_path / "no" / "such"
    assert file_in_the_way(missing) is None
    with pytest.raises(ValueError, match=f"^--x {missing}: folder {missing} does not exist$"):
        check_folder(missing, option="--x")
    assert check_folder(missing, option="--x", missing_ok=True) == missing
    assert not (tmp_path / "no").exists()  # nothing created
    rel = os.path.relpath(tmp_path)
    assert check_folder(rel, option="--x") == tmp_path  # absolute


def test_an_output_that_is_a_folder_reads_the_same_through_every_option(capsys, tmp_path):
    folder = tmp_path / "out"
    folder.mkdir()
    reason = "is a folder; expected a file name"
    assert _one_error(capsys, ["sim", "record", folder, "--stacks", "1", "--profile", PROFILE]) == (
        f"edge sim record: error: OUT.mcap {folder}: {reason} such as {folder / 'run.mcap'}")
    assert _one_error(capsys, ["replay", DATA / "sim-small.mcap", "--recover", "--out", folder]) == (
        f"edge replay: error: --out {folder}: {reason} such as {folder / 'run.mcap'}")
    assert _one_error(capsys, ["decode-images", DATA, "--depth", folder]) == (
        f"edge decode-images: error: --depth {folder}: {reason}")
    assert list(folder.iterdir()) == []


def test_a_symlinked_output_is_written_through_and_stays_a_link(tmp_path):
    """`recover` renames its finished file onto the output: onto a link's target, not the link."""
    real = tmp_path / "real"
    real.mkdir()
    link = tmp_path / "link.mcap"
    link.symlink_to(real / "t.mcap")  # broken: the file it names does not exist yet
    check_record_path(link)  # nothing there to overwrite
    recover(DATA / "sim-small.mcap", link)
    assert link.is_symlink() and os.readlink(link) == str(real / "t.mcap")
    assert RecordingReader(real / "t.mcap").complete and sorted(p.name for p in tmp_path.iterdir()) == ["link.mcap", "real"]
    with pytest.raises(ValueError, match=f"^--record {link} already exists; pass --overwrite"):
        check_record_path(link)
    check_record_path(link, overwrite=True)
    recover(DATA / "sim-small.mcap", link)
    assert link.is_symlink() and sorted(p.name for p in real.iterdir()) == ["t.mcap"]
    away = tmp_path / "away.mcap"  # a link into a folder that does not exist is named by that folder
    away.symlink_to(tmp_path / "nope" / "t.mcap")
    with pytest.raises(ValueError, match=f"^--record {away}: folder {tmp_path / 'nope'} does not exist$"):
        check_record_path(away)


def test_a_broken_link_where_a_folder_should_be_is_named_as_one(tmp_path):
    gone = tmp_path / "gone"
    gone.symlink_to(tmp_path / "missing")
    with pytest.raises(ValueError, match=f"^--x out.png: {gone} is a broken symbolic link \\(to {tmp_path / 'missing'}\\), "
                                         "not a folder$"):
        check_folder(gone / "sub", option="--x", path="out.png")
