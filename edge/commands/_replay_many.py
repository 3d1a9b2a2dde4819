"""``edge replay DIR_OR_GLOB ... [--workers N] [--address ADDR] [--report report.json]``.

Many recordings: serial in this process by default (or ``--workers 1``), on Ray with
``--workers N`` > 1 (local instance, ``num_cpus=N``) or ``--address`` (an existing cluster).
Prints one summary table; exit 0 when every file reproduced its depth bit for bit, 1 otherwise
(a mismatch or a file that failed), 2 for a usage error (nothing matched, Ray missing).
"""

from __future__ import annotations

import argparse
import glob
import json
import os
import sys
import time

from ._args import check_output_file


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("more", nargs="*", metavar="MORE", default=[],  # a default: not named as required
                   help="more recordings; FILE and these may also be directories (their *.mcap) or glob "
                        "patterns such as 'recs/*.mcap': then every file is replayed and one table printed")
    p.add_argument("--workers", type=int, metavar="N",
                   help="replay many recordings on a local Ray instance of N workers, one file per task "
                        "(needs pip install 'edge[fleet]'); default / 1: one after the other in this process")
    p.add_argument("--address", metavar="ADDR",
                   help="run the replays on the existing Ray cluster at ADDR (e.g. ray://head:10001, head:6379 "
                        "or auto), as many at once as it has CPUs; its nodes need edge installed")
    p.add_argument("--report", metavar="REPORT.json", help="also write the per-file results as JSON (checked before the replays; a recording is refused, "
                        "never overwritten)")


def is_many(args: argparse.Namespace) -> bool:
    """True for the many-recordings form (several files, a directory, a pattern or a fleet option)."""
    spec = args.file
    return bool(args.more or args.workers is not None or args.address or args.report or os.path.isdir(spec)
                or (not os.path.exists(spec) and glob.has_magic(spec)))


def replay_many(args: argparse.Namespace) -> int:
    from edge.io.mcap_reader import MCAP_MAGIC
    from edge.io.replay_many import find_recordings, replay_serial, report_dict, summary_lines

    for flag, value in (("--recover", args.recover), ("--publish", args.publish), ("--out", args.out),
                        ("--ply", getattr(args, "ply", None))):
        if value:
            raise ValueError(f"{flag} replays one recording; it cannot be combined with several files, "
                             "a directory, a pattern, --workers, --address or --report")
    if args.workers is not None and args.workers < 1:
        raise ValueError(f"expected --workers >= 1, got {args.workers}")
    if args.report:
        check_output_file(args.report, option="--report")  # before the replays, not after them
    use_ray = args.address is not None or (args.workers or 1) > 1
    if use_ray:
        from edge.io.fleet import require_ray

        require_ray("--workers > 1" if args.address is None else "--address")  # before any work
    paths = find_recordings([args.file, *args.more])
    if args.report and os.path.exists(args.report):  # the JSON replaced a recording (even one replayed here)
        with open(args.report, "rb") as f:
            recording = f.read(len(MCAP_MAGIC)) == MCAP_MAGIC
        if recording or any(os.path.samefile(args.report, p) for p in paths):
            raise ValueError(f"--report {args.report}: is a recording; write the report to a .json file")
    expected = None
    if args.profile:
        from edge.profiles import load_profile

        expected = load_profile(args.profile)
    workers = args.workers or 1
    engine = "serial" if not use_ray else ("ray local" if args.address is None else f"ray {args.address}")
    print(f"edge replay: {len(paths)} recordings, {engine}" + (f", {workers} workers" if use_ray and args.address is None else ""),
          flush=True)
    from tqdm import tqdm

    start = time.perf_counter()
    timings: dict[str, float] = {}
    with tqdm(total=len(paths), unit="file", file=sys.stderr, disable=None) as bar:
        def done(result) -> None:
            bar.update(1)

        if use_ray:
            from edge.io.fleet import replay_on_ray

            results = replay_on_ray(paths, workers=workers, address=args.address,
                                    expected_profile=expected, on_done=done, timings=timings)
        else:
            results = replay_serial(paths, expected, on_done=done)
    wall = time.perf_counter() - start
    if args.address is not None and timings.get("cpus"):
        workers = int(timings["cpus"])
    for line in summary_lines(results, wall_s=wall, workers=workers, engine=engine):
        print(line)
    if "startup_s" in timings:
        print(f"(of which {timings['startup_s']:.1f} s starting Ray)")
    report = report_dict(results, wall_s=wall, workers=workers, engine=engine, address=args.address)
    report["startup_s"] = round(timings.get("startup_s", 0.0), 3)
    if args.report:
        try:
            with open(args.report, "w") as f:
                json.dump(report, f, indent=1)
        except OSError as exc:
            raise ValueError(f"could not write --report {args.report!r}: {exc.strerror}") from None
        print(f"wrote {args.report}")
    return 0 if report["all_identical"] else 1
