"""``edge sim record OUT.mcap --stacks N [--profile P]``: recordings from the simulator, no service."""

from __future__ import annotations

import argparse
import sys
from typing import Any


def register(subparsers: Any) -> None:
    p = subparsers.add_parser("sim", help="simulator utilities (record MCAP without the service)",
                              description="Simulator utilities.")
    sub = p.add_subparsers(dest="sim_command", metavar="SIM_COMMAND")
    r = sub.add_parser("record", help="record N simulated stacks (raw frames + decoded depth) to MCAP",
                       description="Render N stacks of the profile's moving scene with the simulated sensor "
                                   "and write them to MCAP, with the depth, confidence (and error probability) the service "
                                   "computes for them (so `edge replay` can check the file bit for bit).")
    r.add_argument("out", metavar="OUT.mcap", help="recording to write")
    r.add_argument("--stacks", type=int, required=True, metavar="N", help="stacks to record")
    r.add_argument("--profile", default="sim-dlp", help="firmware profile name or TOML path (default: sim-dlp)")
    r.add_argument("--first-stack", type=int, default=0, metavar="K", help="stack id (scene time) to start at (default 0)")
    r.add_argument("--raw-only", action="store_true", help="record frames only, no depth / confidence")
    r.add_argument("--overwrite", action="store_true", help="let OUT.mcap replace an existing file")
    r.set_defaults(func=record)
    p.set_defaults(func=lambda args: (p.print_help(), 2)[1])


def record_simulation(out: str, profile, stacks: int, *, first_stack: int = 0, outputs: bool = True,
                      progress: bool = False) -> dict[str, Any]:
    """Render ``stacks`` stacks with the profile's simulated sensor (max speed; `open_sensor` "sim":
    columns, dots, curtain or event simulator) into ``out``; returns counts."""
    from edge.runtime.assembly import StackAssembler
    from edge.runtime.pipelines import make_pipeline
    from edge.io.recording import EdgeRecorder, frame_role
    from edge.sensors import open_sensor
    from edge.sensors.base import EndOfStream

    if stacks < 1:
        raise ValueError(f"--stacks must be >= 1, got {stacks}")
    if first_stack < 0:  # checked before OUT.mcap is created (the simulator fails on it half-way)
        raise ValueError(f"--first-stack must be >= 0, got {first_stack}")
    sensor = open_sensor(profile, "sim", stacks=stacks, max_speed=True, first_stack=first_stack)
    pipeline = make_pipeline(profile) if outputs else None
    assembler = StackAssembler(sensor.schedule)
    counts = {"frames": 0, "stacks": 0, "outputs": 0}
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=stacks, unit="stack", file=sys.stderr, disable=None)  # None: only on a terminal
    with EdgeRecorder(out, profile, sensor_metadata=sensor.info.metadata) as rec:
        sensor.start()
        try:
            while True:
                try:
                    frame = sensor.read(5.0)
                except EndOfStream:
                    break
                if frame is None:
                    continue
                rec.write_record(frame)
                counts["frames"] += 1
                stack = assembler.push(frame)
                if stack is None:
                    continue
                counts["stacks"] += 1
                if bar is not None:
                    bar.update(1)
                if pipeline is not None:
                    result = pipeline.process(stack, getattr(sensor, "capture_masked", None))
                    for extra in result.extra_frames:
                        rec.write_frame(extra, role=frame_role(extra.projector_frame))
                        counts["frames"] += 1
                    rec.write_depth(result.depth_mm, result.confidence, timestamp_ns=result.timestamp_ns,
                                    stack=result.stack, sequence=result.sequence, edc_rounds=result.edc_rounds,
                                    valid_fraction=round(result.valid_fraction, 6), error=result.error)
                    counts["outputs"] += 1
        finally:
            sensor.stop()
            if bar is not None:
                bar.close()
    return counts


def record(args: argparse.Namespace) -> int:
    from edge.profiles import load_profile

    from edge.io.recording import check_record_path

    profile = load_profile(args.profile)
    check_record_path(args.out, overwrite=args.overwrite, inputs=(args.profile,), option="OUT.mcap")
    counts = record_simulation(args.out, profile, args.stacks, first_stack=args.first_stack,
                               outputs=not args.raw_only, progress=True)
    print(f"edge sim record: wrote {counts['stacks']} stacks ({counts['frames']} frames, {counts['outputs']} depth maps) "
          f"of profile {profile.name} to {args.out}")
    return 0
