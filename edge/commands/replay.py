"""``edge replay FILE [--publish] [--recover]``: decode a recording again and check depth bit for bit."""

from __future__ import annotations

import argparse
import os
import sys
from typing import Any


def register(subparsers: Any) -> None:
    p = subparsers.add_parser(
        "replay", help="decode a recording with its recorded profile; check depth bit for bit",
        description="Decode the raw frames of an edge MCAP recording with the recorded profile and compare "
                    "depth and confidence with what the service recorded, bit for bit. Exit 0 when every "
                    "recorded depth map is reproduced, 1 on a mismatch, 2 for an unreadable file. Several files, a directory "
                    "or a glob pattern replay every recording (in parallel on Ray with --workers N) and print one "
                    "table: exit 0 when all are bit-identical, 1 otherwise.")
    p.add_argument("file", metavar="FILE", help="recording (.mcap); or several files, a directory or a glob pattern")
    p.add_argument("--profile", help="expected profile (name or TOML): refuse a recording of another profile")
    p.add_argument("--recover", action="store_true",
                   help="the writer was killed: salvage the complete chunks into FILE.recovered.mcap first")
    p.add_argument("--out", metavar="FILE", help="where --recover writes (default FILE.recovered.mcap)")
    p.add_argument("--overwrite", action="store_true", help="let --recover replace an existing file")
    p.add_argument("--publish", action="store_true", help="republish the decoded depth over zenoh")
    p.add_argument("--listen", action="append", metavar="ENDPOINT", help="zenoh listen endpoint(s) for --publish")
    p.add_argument("--ply", metavar="DIR",
                   help="write the point cloud of every re-decoded depth map to DIR/<device>_<stack>.ply "
                        "(every valid pixel, metres, camera optical frame, grey = confidence)")
    from edge.commands._replay_many import add_arguments

    add_arguments(p)  # many recordings: FILE... / DIR / 'GLOB', --workers, --address, --report
    p.set_defaults(func=replay)


def replay(args: argparse.Namespace) -> int:
    from edge.commands._replay_many import is_many, replay_many
    from edge.io.mcap import RecordingError, recover
    from edge.io.replay import replay_recording

    if is_many(args):
        return replay_many(args)
    path = args.file
    if not os.path.exists(path):
        raise FileNotFoundError(f"recording {path!r} does not exist")
    if args.recover:
        from edge.io.recording import check_record_path

        out = args.out or (path[:-5] if path.endswith(".mcap") else path) + ".recovered.mcap"
        check_record_path(out, overwrite=args.overwrite, inputs=(path,), option="--out" if args.out else "--recover")
        report = recover(path, out)
        print(f"edge replay: {report}")
        path = out
    expected = None
    if args.profile:
        from edge.profiles import load_profile

        expected = load_profile(args.profile)
    sink = bar = None
    callbacks = []
    ply = None
    if args.ply:
        ply = _PlyWriter(args.ply)
        callbacks.append(ply.on_result)
    try:
        if args.publish:
            from edge.io.mcap import RecordingReader
            from edge.profiles import apply_update
            from edge.io.publish import ZenohSink

            profile = RecordingReader(path).profile
            if profile is None:
                raise RecordingError(f"{path}: the recording holds no edge profile; cannot replay it")
            if args.listen:
                profile = apply_update(profile, {"zenoh": {"listen": list(args.listen)}})
            sink = ZenohSink(profile, None)
            callbacks.append(sink.on_result)
        if ply is not None:
            from edge.io.mcap import RecordingReader

            ply.profile = RecordingReader(path).profile

        from tqdm import tqdm

        # a long recording decodes for minutes: a bar on a terminal (off when stderr is not one)
        bar = tqdm(total=_depth_maps(path), desc="replay", unit="depth map", file=sys.stderr, disable=None,
                   leave=False)
        callbacks.append(lambda result: bar.update(1))

        def on_result(result):
            for cb in callbacks:
                cb(result)

        report = replay_recording(path, expected_profile=expected, on_result=on_result)
    except RecordingError as exc:
        print(f"edge replay: error: {exc}", file=sys.stderr)
        return 2
    finally:
        if bar is not None:
            bar.close()
        if sink is not None:
            sink.close()
    for line in report.lines():
        print(line)
    if ply is not None:
        print(f"edge replay: wrote {ply.written} PLY files to {args.ply}")
    if report.mismatches:
        return 1
    if report.problem or report.stacks_compared == 0:
        problem = report.problem or f"{path}: no recorded depth output to compare against"
        print(f"edge replay: error: {problem}", file=sys.stderr)
        return 2
    print("edge replay: depth reproduced bit for bit")
    return 0


def _depth_maps(path: str) -> int | None:
    """Depth maps recorded in ``path`` (its summary's message counts), None without a summary."""
    from edge.io.mcap import RecordingReader

    summary = RecordingReader(path).summary
    if summary is None or summary.statistics is None:
        return None
    counts = summary.statistics.channel_message_counts
    return sum(counts.get(cid, 0) for cid, channel in summary.channels.items() if channel.topic.endswith("/depth"))


class _PlyWriter:
    """One PLY per depth map (`edge.runtime.depth.depth_to_points`, stride 1, `edge.io.ply.write_ply`)."""

    def __init__(self, directory: str) -> None:
        if os.path.exists(directory) and not os.path.isdir(directory):
            raise ValueError(f"--ply: expected a directory, got the file {directory!r}")
        try:
            os.makedirs(directory, exist_ok=True)
        except OSError as exc:
            raise ValueError(f"--ply: cannot create the directory {directory!r}: {exc.strerror or exc}") from None
        self.directory = directory
        self.profile = None
        self.written = 0

    def on_result(self, result) -> None:
        from edge.io.ply import write_ply
        from edge.runtime.depth import camera_matrix, depth_to_points

        geometry = result.geometry if result.geometry is not None else self.profile.geometry
        pts = depth_to_points(result.depth_mm, camera_matrix(geometry))
        grey = result.confidence[result.depth_mm > 0]
        path = os.path.join(self.directory, f"{self.profile.zenoh.device}_{result.stack:06d}.ply")
        try:
            write_ply(path, pts, colors=grey)
        except OSError as exc:
            raise ValueError(f"--ply: cannot write {path!r}: {exc.strerror or exc}") from None
        self.written += 1
