"""Offline replay: decode the frames of a recording with its recorded profile and compare the depth.

`replay_recording(path)` reads the recording stack by stack (`RecordingReader.stacks`), assembles
each stack exactly as the service does (`StackAssembler`: incomplete stacks are dropped and
counted), runs the same `DepthPipeline.process` (EDC rounds get the recorded masked frames back),
and compares depth (and confidence) with what the service recorded, bit for bit.  Every profile
kind replays through its own pipeline (`make_pipeline`); an event recording (``event-dots``) is
read slice by slice from its ``/<device>/events`` topic (`edge.io.event_record.event_stacks`).
A live configuration change the service accepted while recording is replayed from the stack it
first decoded (the ``profile`` of that stack's ``/<device>/stack`` message, `stack_info`): the
pipeline is rebuilt with the recorded profile there.  Recordings made before stacks carried it
hold the change on ``/<device>/config_change`` only; their stacks after it are compared against
the starting profile, and the report says so.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from ..sensors.base import Frame, parse_projector_frame
from edge.runtime.assembly import StackAssembler
from edge.runtime.pipelines import make_pipeline, pipeline_kind
from edge.runtime.result import DepthResult


@dataclass
class ReplayReport:
    """What a replay found.  ``ok`` is True when every compared stack matched and the file was whole."""

    path: str
    profile: str = ""
    stacks_read: int = 0
    stacks_compared: int = 0
    stacks_matched: int = 0
    stacks_without_output: int = 0
    stacks_incomplete: int = 0
    profile_changes: int = 0
    mismatches: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)  # what explains the mismatches (not counted as one)
    problem: str = ""

    @property
    def ok(self) -> bool:
        return not self.mismatches and not self.problem and self.stacks_compared > 0

    def lines(self) -> list[str]:
        out = [f"{self.path}: profile {self.profile!r}, {self.stacks_read} stacks read, "
               f"{self.stacks_compared} compared, {self.stacks_matched} bit-exact, "
               f"{len(self.mismatches)} differ, {self.stacks_without_output} complete without a recorded "
               f"output (not decoded by the service), {self.stacks_incomplete} incomplete (dropped)"
               + (f", {self.profile_changes} live profile change(s) replayed" if self.profile_changes else "")]
        out += [f"  mismatch: {m}" for m in self.mismatches[:20]]
        out += [f"  note: {n}" for n in self.notes]
        if self.problem:
            out.append(f"  problem: {self.problem}")
        if self.stacks_compared == 0 and not self.problem:
            out.append("  problem: no recorded depth output to compare against")
        return out


def to_frame(recorded: Any) -> Frame:
    """`edge.io.mcap_reader.RecordedFrame` -> `Frame`."""
    return Frame(recorded.image, int(recorded.sequence), int(recorded.timestamp_ns), float(recorded.exposure_us),
                 int(recorded.projector_frame), int(recorded.stack))


def _describe_diff(name: str, got: np.ndarray, want: np.ndarray) -> str:
    if got.shape != want.shape:
        return f"{name} shape {got.shape} != recorded {want.shape}"
    diff = got != want
    ys, xs = np.nonzero(diff)
    return (f"{name}: {int(diff.sum())} of {diff.size} pixels differ (first at y={ys[0]}, x={xs[0]}: "
            f"{got[ys[0], xs[0]]} vs recorded {want[ys[0], xs[0]]})")


def replay_recording(path: str | os.PathLike[str], *, expected_profile: Any = None,
                     on_result: Callable[[DepthResult], None] | None = None) -> ReplayReport:
    """Replay ``path`` (see module docstring).  Raises `edge.io.mcap.RecordingError` for a file that is
    not a recording or has no usable profile; a truncated/corrupt tail ends the replay with
    ``report.problem`` set after everything readable was replayed."""
    from edge.io.mcap import RecordingError, RecordingReader

    reader = RecordingReader(path, expected_profile=expected_profile, strict=False)
    if reader.profile is None:
        if reader.head_problem:  # cut or corrupt before its profile metadata was written
            raise RecordingError(f"{reader.head_problem}; the file ends before its profile, nothing to replay")
        raise RecordingError(f"{os.fspath(path)}: the recording holds no edge profile; cannot replay it")
    report = ReplayReport(os.fspath(path), reader.profile.name)
    pipeline = make_pipeline(reader.profile)
    assembler = StackAssembler(pipeline.schedule)
    old_format = reader.format < 2
    if pipeline_kind(reader.profile) == "event-dots":
        return _replay_events(reader, pipeline, assembler, report, on_result, path, old_format)
    try:
        for recorded in reader.stacks():
            if not recorded.frames:
                continue
            report.stacks_read += 1
            regular = [to_frame(f) for f in recorded.frames if parse_projector_frame(f.projector_frame).edc_round == 0]
            masked = [to_frame(f) for f in recorded.frames if parse_projector_frame(f.projector_frame).edc_round > 0]
            pipeline = _switch(report, path, recorded.stack, recorded.info, pipeline)
            if recorded.output is None:
                _count_without_output(report, len(regular), len(pipeline.schedule))
                continue
            stack = None
            for frame in regular:
                stack = assembler.push(frame, received_ns=frame.timestamp_ns) or stack
            if stack is None:
                assembler.flush()
                continue
            out = recorded.output

            def recorded_masked(stack_id: int, edc_round: int, rows: np.ndarray) -> list[Frame]:
                got = [f for f in masked if parse_projector_frame(f.projector_frame).edc_round == edc_round]
                if len(got) != len(rows):
                    raise ValueError(f"stack {stack_id}: EDC round {edc_round} asks for {len(rows)} frames, "
                                     f"the recording holds {len(got)}")
                return got

            result = pipeline.process(stack, recorded_masked)
            _compare(report, recorded.stack, result, out, on_result, old_format)
        assembler.flush()
    except RecordingError as exc:  # strict=False normally reports via reader.problem; be safe
        report.problem = str(exc)
    return _finish(report, reader, assembler)


def _switch(report: ReplayReport, path, stack_id: int, info: dict | None, pipeline: Any) -> Any:
    """The pipeline for a recorded stack: rebuilt with the profile its ``/stack`` info carries (a live
    change took effect there; applied whether or not the stack has a depth map, so a later stack
    is not decoded with the old one), else ``pipeline``."""
    changed = (info or {}).get("profile")
    if changed is None:
        return pipeline
    report.profile_changes += 1
    return make_pipeline(_changed_profile(path, stack_id, changed))


def _count_without_output(report: ReplayReport, frames: int, per_stack: int) -> None:
    """A recorded stack with no depth map (dropped stale, a decode error, the stop): complete or not,
    counted without the assembler, which would take a late-handed stack as out of order."""
    if frames >= per_stack:
        report.stacks_without_output += 1
    else:
        report.stacks_incomplete += 1


def _finish(report: ReplayReport, reader: Any, assembler: StackAssembler) -> ReplayReport:
    """The counts and problems every replay ends with."""
    report.stacks_incomplete += assembler.counters.stacks_incomplete
    if reader.problem and not report.problem:
        report.problem = reader.problem
    if report.mismatches and not report.profile_changes and "config_change" in reader.leaves_seen:
        report.notes.append("the recording holds live config changes (/config_change) but no stack says "
                            "where they took effect (recorded before stacks carried their profile): the "
                            "stacks after a change were decoded with the starting profile")
    return report


def _changed_profile(path: str | os.PathLike[str], stack_id: int, data: Any):
    """The `Profile` a recorded stack's info names (a live change); `RecordingError` if invalid."""
    from edge.io.mcap import RecordingError
    from edge.io.mcap_reader import recorded_profile_dict
    from edge.profiles import ProfileError, profile_from_dict

    try:
        return profile_from_dict(recorded_profile_dict(data), source=f"{os.fspath(path)} (stack {stack_id})")
    except (ValueError, ProfileError) as exc:
        raise RecordingError(f"{os.fspath(path)}: the profile recorded at stack {stack_id} (a live change) is "
                             f"invalid: {exc}") from None


def _compare(report: ReplayReport, stack_id: int, result: DepthResult, out: Any,
             on_result: Callable[[DepthResult], None] | None, old_format: bool = False) -> None:
    """Compare one replayed result with the recorded output (``old_format``: a recording of format 1,
    whose valid pixels may hold confidence 0, `_old_zero_confidence`)."""
    if on_result is not None:
        on_result(result)
    report.stacks_compared += 1
    problems = []
    if not np.array_equal(result.depth_mm, out.depth_mm):
        problems.append(_describe_diff("depth", result.depth_mm, out.depth_mm))
    if not np.array_equal(result.confidence, out.confidence) and not (old_format and _old_zero_confidence(result, out)):
        problems.append(_describe_diff("confidence", result.confidence, out.confidence))
    recorded_error = getattr(out, "error", None)
    if recorded_error is not None or result.error is not None:  # bit for bit, NaN included
        if recorded_error is None or result.error is None:
            problems.append(f"error probability: {'recorded' if result.error is None else 'computed'} but not "
                            f"{'computed' if result.error is None else 'recorded'}")
        elif (result.error.shape != recorded_error.shape
              or result.error.astype("<f4").tobytes() != recorded_error.astype("<f4").tobytes()):
            problems.append(_describe_diff("error", result.error.view(np.uint32), recorded_error.view(np.uint32))
                            if result.error.shape == recorded_error.shape else
                            f"error shape {result.error.shape} != recorded {recorded_error.shape}")
    if problems:
        report.mismatches.append(f"stack {stack_id}: " + "; ".join(problems))
    else:
        report.stacks_matched += 1


def _old_zero_confidence(result: DepthResult, out: Any) -> bool:
    """Whether the confidences differ only where a recording made before valid pixels got a
    confidence of at least 1 (`edge.runtime.depth.confidence_to_u8`) has 0 on valid depth and the
    replay 1: the same decode, the old rounding."""
    got, want = result.confidence, out.confidence
    if got.shape != want.shape:
        return False
    diff = got != want
    return bool(((want[diff] == 0) & (got[diff] == 1) & (out.depth_mm[diff] > 0)).all())


def _replay_events(reader: Any, pipeline: Any, assembler: StackAssembler, report: ReplayReport,
                   on_result: Callable[[DepthResult], None] | None, path, old_format: bool) -> ReplayReport:
    """The event-recording branch of `replay_recording` (the same steps over event slices)."""
    from edge.io.mcap import RecordingError

    from .event_record import event_stacks

    try:
        for rec in event_stacks(reader):
            if not rec.slices:
                continue
            report.stacks_read += 1
            pipeline = _switch(report, path, rec.stack, rec.info, pipeline)
            if rec.output is None:
                _count_without_output(report, len(rec.slices), len(pipeline.schedule))
                continue
            stack = None
            for s in rec.slices:
                stack = assembler.push(s, received_ns=s.timestamp_ns) or stack
            if stack is None:
                assembler.flush()
                continue
            _compare(report, rec.stack, pipeline.process(stack), rec.output, on_result, old_format)
        assembler.flush()
    except (RecordingError, ValueError) as exc:
        report.problem = str(exc)
    return _finish(report, reader, assembler)
