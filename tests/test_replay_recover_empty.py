"""`edge replay --recover` on a recording with no complete chunk (cut inside its first chunk, or only
its header and metadata) wrote a valid, EMPTY "recovered" MCAP; a user could delete the original
believing it salvaged.  Now it refuses with one line naming the file, exit 2, and writes nothing."""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader

from edge.cli import main
from edge.io.mcap import Recorder, RecordingError, RecordingReader, recover
from edge.profiles import load_profile


@pytest.fixture(scope="module")
def recording(tmp_path_factory) -> Path:
    """A finished recording of the project's writer: 4 stacks of 5 raw frames, small chunks."""
    path = tmp_path_factory.mktemp("rec") / "rec.mcap"
    with Recorder(path, load_profile("sim-dlp"), chunk_size=16 * 1024) as rec:
        for seq in range(20):
            img = np.random.default_rng(seq).integers(0, 256, (48, 64), dtype=np.uint8)
            rec.write_raw(img, sequence=seq, timestamp_ns=seq, stack=seq // 5, projector_frame=seq % 5)
    return path


def _chunk_starts(path: Path) -> list[tuple[int, int]]:
    with open(path, "rb") as f:
        chunks = make_reader(f).get_summary().chunk_indexes
    return sorted((c.chunk_start_offset, c.chunk_length) for c in chunks)


def _header_end(data: bytes) -> int:
    """Byte just after the Header record (magic, opcode 0x01, uint64 length, content)."""
    assert data[8] == 0x01
    return 8 + 9 + struct.unpack_from("<Q", data, 9)[0]


def _cuts(recording: Path) -> dict[str, bytes]:
    data = recording.read_bytes()
    (first, length), (second, _) = _chunk_starts(recording)[:2]
    assert second > first + length  # several chunks: the cut below loses the first one only
    return {
        "inside the first chunk": data[:first + length // 2],
        "before the first chunk (header, metadata)": data[:first],
        "only the header": data[:_header_end(data)],
    }


@pytest.mark.parametrize("case", ["inside the first chunk", "before the first chunk (header, metadata)",
                                  "only the header"])
def test_recover_refuses_a_file_with_nothing_to_salvage(tmp_path, capsys, recording, case):
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(_cuts(recording)[case])
    before = cut.read_bytes()
    assert main(["replay", str(cut), "--recover"]) == 2
    captured = capsys.readouterr()
    err = captured.err.strip().splitlines()
    assert len(err) == 1 and "Traceback" not in captured.err, err
    assert err[0].startswith(f"edge replay: error: {cut}: nothing could be recovered")
    assert err[0].endswith("nothing was written") and "recovered " not in captured.out
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cut.mcap"]  # no output, no leftover part file
    assert cut.read_bytes() == before


def test_an_existing_output_is_kept_when_nothing_could_be_recovered(tmp_path, capsys, recording):
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(_cuts(recording)["inside the first chunk"])
    out = tmp_path / "out.mcap"
    out.write_bytes(recording.read_bytes())
    assert main(["replay", str(cut), "--recover", "--out", str(out), "--overwrite"]) == 2
    assert "nothing could be recovered" in capsys.readouterr().err
    assert out.read_bytes() == recording.read_bytes()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cut.mcap", "out.mcap"]


def test_library_recover_raises_and_writes_nothing(tmp_path, recording):
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(_cuts(recording)["inside the first chunk"])
    with pytest.raises(RecordingError, match=r"cut\.mcap: nothing could be recovered: no complete chunk holds a "
                                             r"message \(.*byte \d+\); nothing was written$"):
        recover(cut, tmp_path / "out.mcap")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cut.mcap"]


def test_one_complete_chunk_is_still_recovered(tmp_path, recording):
    """The refusal is for nothing at all: a file cut inside its second chunk salvages the first."""
    data = recording.read_bytes()
    (_, _), (second, length) = _chunk_starts(recording)[:2]
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[:second + length // 2])
    out = tmp_path / "out.mcap"
    report = recover(cut, out)
    assert report.chunks == 1 and report.messages > 0 and not report.complete_input
    frames = list(RecordingReader(out).frames())
    assert 0 < len(frames) == report.topics["/sim-dlp/raw"] < 20
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cut.mcap", "out.mcap"]  # the part file renamed
