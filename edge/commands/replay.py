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
                    "recorded depth map is reproduced, 1 on a mismatch, 2 for an unreadable file.")
    p.add_argument("file", metavar="FILE")
    p.add_argument("--profile", help="expected profile (name or TOML): refuse a recording of another profile")
    p.add_argument("--recover", action="store_true",
                   help="the writer was killed: salvage the complete chunks into FILE.recovered.mcap first")
    p.add_argument("--out", metavar="FILE", help="where --recover writes (default FILE.recovered.mcap)")
    p.add_argument("--publish", action="store_true", help="republish the decoded depth over zenoh")
    p.add_argument("--listen", action="append", metavar="ENDPOINT", help="zenoh listen endpoint(s) for --publish")
    p.set_defaults(func=replay)


def replay(args: argparse.Namespace) -> int:
    from edge.io.mcap import RecordingError, recover
    from edge.runtime.replay import replay_recording

    path = args.file
    if not os.path.exists(path):
        raise FileNotFoundError(f"recording {path!r} does not exist")
    if os.path.isdir(path):
        raise ValueError(f"recording {path!r} is a directory, expected an MCAP file")
    if args.recover:
        out = args.out or (path[:-5] if path.endswith(".mcap") else path) + ".recovered.mcap"
        report = recover(path, out)
        print(f"edge replay: {report}")
        path = out
    expected = None
    if args.profile:
        from edge.profiles import load_profile

        expected = load_profile(args.profile)
    sink = None
    try:
        if args.publish:
            from edge.io.mcap import RecordingReader
            from edge.profiles import apply_update
            from edge.runtime.publish import ZenohSink

            profile = RecordingReader(path).profile
            if profile is None:
                raise RecordingError(f"{path}: the recording holds no edge profile; cannot replay it")
            if args.listen:
                profile = apply_update(profile, {"zenoh": {"listen": list(args.listen)}})
            sink = ZenohSink(profile, None)
        report = replay_recording(path, expected_profile=expected,
                                  on_result=sink.on_result if sink is not None else None)
    except RecordingError as exc:
        print(f"edge replay: error: {exc}", file=sys.stderr)
        return 2
    finally:
        if sink is not None:
            sink.close()
    for line in report.lines():
        print(line)
    if report.mismatches:
        return 1
    if report.problem or report.stacks_compared == 0:
        problem = report.problem or f"{path}: no recorded depth output to compare against"
        print(f"edge replay: error: {problem}", file=sys.stderr)
        return 2
    print("edge replay: depth reproduced bit for bit")
    return 0
