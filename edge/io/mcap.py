"""MCAP recording for edge: `Recorder` (write), `RecordingReader` (read), `recover` (salvage).

The file layout (topics, schemas, metadata) is documented in `edge.io.mcap_format`; each class is
documented in its own module (`edge.io.mcap_writer`, `edge.io.mcap_reader`, `edge.io.mcap_recover`).
Images use Foxglove's protobuf schemas (foxglove.RawImage, foxglove.CameraCalibration), so files
open in Foxglove; `tools/bench_mcap_encoding.py` measures protobuf against JSON-schema encoding.

    from edge.io.mcap import Recorder, RecordingReader, recover
"""

from .mcap_format import topics
from .mcap_reader import (
    NotMcapError,
    ProfileMismatchError,
    RecordedFrame,
    RecordedMessage,
    RecordedOutput,
    RecordedStack,
    RecordingError,
    RecordingReader,
    TruncatedRecordingError,
)
from .mcap_recover import RecoveryReport, recover
from .mcap_writer import Recorder

__all__ = [
    "Recorder",
    "RecordingReader",
    "RecordedFrame",
    "RecordedMessage",
    "RecordedOutput",
    "RecordedStack",
    "RecordingError",
    "NotMcapError",
    "TruncatedRecordingError",
    "ProfileMismatchError",
    "RecoveryReport",
    "recover",
    "topics",
]
