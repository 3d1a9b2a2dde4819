"""RecordingReader parses (and CRC-checks) a file's summary once, not on every access."""

from __future__ import annotations

import shutil
from pathlib import Path

import edge.io.mcap_reader as mcap_reader
from edge.io.mcap import RecordingReader

COMMITTED = Path(__file__).parent / "data" / "sim-small.mcap"


def test_summary_and_complete_parse_the_file_once(tmp_path, monkeypatch):
    path = tmp_path / "rec.mcap"
    shutil.copyfile(COMMITTED, path)
    calls = []
    real = mcap_reader.make_reader

    def counting(f, **kw):
        calls.append(kw)
        return real(f, **kw)

    monkeypatch.setattr(mcap_reader, "make_reader", counting)
    reader = RecordingReader(path)
    assert calls == []
    first = reader.summary
    assert first is not None and reader.complete and reader.complete
    assert reader.summary is first
    assert calls == [{"validate_crcs": True}]      # one CRC-checked parse for all of the above
    # a file that changes on disk is parsed again: cut it, and it is no longer complete
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    assert not reader.complete and reader.summary is None
    assert len(calls) == 2
