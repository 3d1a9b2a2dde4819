"""Benchmark the service's EDC stage against the decode it checks, in one process.

    python tools/bench_edc.py [--profile sim-dlp] [--rounds 3] [--scene steps] [--repeats 7]

Renders a few stacks of the profile's simulated sensor (640x480, ecc-22-10 for sim-dlp), then for
each stack times, in this process: the soft decode of the stack (`DepthPipeline.decode`, the
baseline every stack pays anyway) and the EDC stage with ``edc.rounds`` masked rounds
(`edge.runtime.edc_stage.run_adaptive`: round 1 = the check of the stack, then the masked rounds,
the simulator rendering the masked frames on request).  Printed: medians of wall time AND of
process CPU time (all threads; robust to other load on the machine), the per-round decode times,
the masked-capture time, the open pixels per round and the frames per depth map.  The EDC stage
keeps up with the camera when soft decode + EDC stays under the stack period
(frames per stack / camera rate, 200 ms for sim-dlp).
"""

from __future__ import annotations

import argparse
import time

import numpy as np


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--profile", default="sim-dlp",
                    help="firmware profile, a 'columns' profile with the sim sensor (default %(default)s)")
    ap.add_argument("--rounds", type=int, default=3,
                    help="edc.rounds: masked rounds after the stack's own check (default %(default)s)")
    ap.add_argument("--scene", default=None, help="sim scene (default: the profile's)")
    ap.add_argument("--stacks", type=int, default=3, help="different stacks (poses; default %(default)s)")
    ap.add_argument("--repeats", type=int, default=7, help="timed runs; medians are reported (default 7)")
    args = ap.parse_args(argv)

    from edge.profiles import apply_update, load_profile
    from edge.runtime.assembly import StackAssembler
    from edge.runtime.edc_stage import run_adaptive
    from edge.runtime.pipeline import DepthPipeline
    from edge.sensors.sim import SimSensor

    update = {"edc": {"rounds": int(args.rounds)}}
    if args.scene:
        update["sim"] = {"scene": args.scene}
    profile = apply_update(load_profile(args.profile), update)
    pipe = DepthPipeline(profile)
    pipe.warm_up()
    sensor = SimSensor(profile, stacks=args.stacks, max_speed=True, poses=args.stacks)
    asm = StackAssembler(pipe.schedule)
    sensor.start()
    stacks = []
    try:
        while len(stacks) < args.stacks:
            frame = sensor.read(10.0)
            stack = asm.push(frame) if frame is not None else None
            if stack is not None:
                stacks.append(stack)
        prepared = []
        for s in stacks:
            images = pipe.stacked(s.frames)
            d = pipe.decode(images[: pipe.n], images[pipe.n], images[pipe.n + 1])
            col = np.where(d.valid, d.column, -1).astype(np.int32)
            prepared.append((s, images, col, np.asarray(d.confidence, np.float32)))
            run_adaptive(pipe, s, images, col, d.confidence, sensor.capture_masked)  # compile every path
        rec: dict[str, list[float]] = {"soft_wall": [], "soft_cpu": [], "edc_wall": [], "edc_cpu": []}
        last = None
        for _ in range(args.repeats):
            for s, images, col, conf in prepared:
                w0, c0 = time.perf_counter(), time.process_time()
                pipe.decode(images[: pipe.n], images[pipe.n], images[pipe.n + 1])
                w1, c1 = time.perf_counter(), time.process_time()
                last = run_adaptive(pipe, s, images, col, conf, sensor.capture_masked)
                w2, c2 = time.perf_counter(), time.process_time()
                rec["soft_wall"].append(w1 - w0)
                rec["soft_cpu"].append(c1 - c0)
                rec["edc_wall"].append(w2 - w1)
                rec["edc_cpu"].append(c2 - c1)
    finally:
        sensor.stop()
    med = {k: 1e3 * float(np.median(v)) for k, v in rec.items()}
    period = 1e3 * len(pipe.schedule) / profile.camera.rate_hz
    print(f"profile {profile.name} ({profile.sim.scene}): {profile.camera.width}x{profile.camera.height}, "
          f"{profile.code.name}, edc.rounds = {profile.edc.rounds}; {len(rec['edc_wall'])} runs; "
          f"stack period {period:.0f} ms")
    print(f"soft decode (baseline)  : wall {med['soft_wall']:.1f} ms, CPU {med['soft_cpu']:.1f} ms")
    print(f"EDC stage               : wall {med['edc_wall']:.1f} ms, CPU {med['edc_cpu']:.1f} ms "
          f"({med['edc_cpu'] / max(med['soft_cpu'], 1e-9):.2f}x the decode's CPU)")
    print(f"  rounds {last.rounds}, decode ms per round {list(last.round_ms)}, masked capture ms "
          f"{list(last.capture_ms)} (the simulator), open pixels after each round {list(last.open_pixels)}, "
          f"frames per depth map {len(stacks[0].frames) + len(last.extra)}")
    print(f"soft + EDC wall {med['soft_wall'] + med['edc_wall']:.1f} ms of the {period:.0f} ms stack period")
    return 0


if __name__ == "__main__":
    from edge.cli import tool_main

    raise SystemExit(tool_main(main, __file__))
