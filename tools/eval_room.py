"""Several devices in one room: tables and figures into docs/results/room/.

    OPENBLAS_NUM_THREADS=1 python tools/eval_room.py [--out docs/results/room] [--max-devices 8] [--quick]

Writes
  codes.md         guaranteed-margin tables N x L (exact worst case of the SUM of N-1 foreign devices,
                   `edge.codes.source_room`), with no coding and time-division, for aperiodic frame
                   streams (DLP, curtains), periodic frame streams (dot projectors) and event sensors;
  slots.md/.png    slot-level simulation (`edge.source.room_slots`): own signal kept and false
                   detections for N = 1..8: joint filter, plain matched filter, no coding, time-division;
  devices.md/.png  the room simulator (`edge.sensors.room_model`, one process, every device's light
                   with its own offset, drift and power) per device kind - light curtain, event-camera
                   dots, source-coded DLP - for N = 1..8: depth error vs ground truth, false detections
                   and own signal kept vs the same device alone, coded vs uncoded vs time-division, and
                   the frame-rate cost of each;
  README.md        all tables and the command.

Device runs use the small test profiles (tests/data/profiles: 160x120 cameras) so the whole sweep runs
in minutes on two cores; the family is [room] family_size = 8 codes of length 12 for every kind.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # small least-squares problems: threads only contend

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from edge.codes.source_room import format_table, margin_table, room_family  # noqa: E402
from edge.commands._args import output_dir  # noqa: E402
from edge.source.room_slots import SlotScenario, evaluate  # noqa: E402

PROFILES = ROOT / "tests" / "data" / "profiles"
KINDS = {  # kind -> (profile, uncoded source code (plain on/off, ambient cancels), label)
    "light curtain": (PROFILES / "room-curtain.toml", "10", "curtain"),
    "event-camera dots": (PROFILES / "room-events.toml", "10", "events"),
    "DLP columns (ecc-22-10)": (PROFILES / "test-small.toml", "", "dlp"),
}
FAMILY_SIZE, CODE_LENGTH = 8, 12
STACKS = (2, 5)


def codes_tables(out: Path, quick: bool) -> str:
    lengths = (4, 6, 8, 10, 12) if quick else (4, 6, 8, 10, 12, 14, 16)
    parts = ["# Guaranteed margins of room families", "",
             "Exact worst case of the sum of N-1 unsynchronised foreign devices at any fractional offset "
             "(integer cyclic shifts attain it: `edge/codes/source_room.py`), each foreign device at most "
             "as bright as the own one (P = 1). Entry: margin (fraction of the own level; > 0 = a threshold "
             "separates own light from any foreign sum) [largest per-device power ratio with a guarantee]. "
             "Frame cost: camera frames per projected frame.", ""]
    for kind, stream, what in (("frame", "aperiodic", "frame sensors, foreign on/off symbols (DLP patterns, light curtains)"),
                               ("frame", "periodic", "frame sensors, foreign devices repeating their code (dot projectors)"),
                               ("event", "periodic", "event sensors (edge counts), dot projectors")):
        t = time.perf_counter()
        rows = margin_table(range(2, 17), lengths, kind=kind, stream=stream)
        parts += [f"## {what}", "", format_table(rows), "", f"(computed in {time.perf_counter() - t:.0f} s)", ""]
    text = "\n".join(parts)
    (out / "codes.md").write_text(text + "\n")
    return text


def slots_table(out: Path, max_n: int, pixels: int) -> str:
    fam = room_family(FAMILY_SIZE, CODE_LENGTH)
    rows = {}
    for n in range(1, max_n + 1):
        rows[n] = evaluate(SlotScenario(n, length=CODE_LENGTH, pixels=pixels, seed=n), fam)
        print(f"slots N={n}: " + ", ".join(f"{k} {v['own_kept']:.3f}/{v['false']:.4f}" for k, v in rows[n].items()),
              flush=True)
    schemes = ("joint", "matched", "uncoded", "time-division")
    cost = {"joint": f"{CODE_LENGTH}", "matched": f"{CODE_LENGTH}", "uncoded": "1", "time-division": "N (sync)"}
    lines = ["| N | " + " | ".join(f"{s} kept / false (cost {cost[s]})" for s in schemes) + " |",
             "|---|" + "---|" * len(schemes)]
    for n, r in rows.items():
        lines.append(f"| {n} | " + " | ".join(f"{r[s]['own_kept']:.3f} / {r[s]['false']:.4f}" for s in schemes) + " |")
    text = "\n".join(lines)
    (out / "slots.md").write_text(text + "\n")
    fig, ax = plt.subplots(1, 2, figsize=(10, 3.6))
    ns = list(rows)
    for s in schemes:
        ax[0].plot(ns, [rows[n][s]["own_kept"] for n in ns], "o-", label=s)
        ax[1].plot(ns, [rows[n][s]["false"] for n in ns], "o-", label=s)
    ax[0].set(title="own signal kept", xlabel="devices in the room N", ylim=(0, 1.02))
    ax[1].set(title="false detections", xlabel="devices in the room N")
    ax[0].axhline(0.95, color="grey", lw=0.6, ls="--")
    ax[1].axhline(0.005, color="grey", lw=0.6, ls="--")
    ax[0].legend(fontsize=8)
    fig.suptitle(f"Slot-level room simulation (L = {CODE_LENGTH}, foreign <= own, drift 1e-3, noise 0.02)")
    fig.tight_layout()
    fig.savefig(out / "slots.png", dpi=90)
    plt.close(fig)
    return text


def _run(profile, room, stack: int, joint: bool):
    """(depth mm, truth depth mm) of one stack of ``profile`` in ``room``."""
    from edge.runtime.assembly import StackAssembler
    from edge.runtime.pipelines import make_pipeline
    from edge.runtime.room import room_family_for
    from edge.sensors import open_sensor

    sensor = open_sensor(profile, "sim", room=room)
    pipe = make_pipeline(profile)
    if joint and hasattr(pipe, "foreign_sources") and profile.code.source:
        fam = room_family_for(profile)
        pipe.foreign_sources = tuple(fam[m.code].string for m in room.members() if m.device != room.me.device)
    asm = StackAssembler(pipe.schedule)
    result = None
    for pos, payload in enumerate(sensor.render_stack(stack)):
        st = asm.push(sensor._record(payload, pos, stack, pos))
        if st is not None:
            result = pipe.process(st)
    truth = sensor.scene(stack).depth_m * 1000.0
    return result.depth_mm, truth


def _correct(depth, truth) -> np.ndarray:
    return (depth > 0) & (np.abs(depth.astype(np.float64) - truth) <= 0.05 * truth)


def _metrics(depth, alone, truth) -> dict:
    """kept: of the pixels the device alone measures correctly (within 5 % of the ground truth), the
    fraction still correct; false: fraction of pixels with a wrong depth (> 5 % off) or a depth where
    there is no surface; depth err: median |depth - truth| over valid pixels (mm)."""
    ok_alone = _correct(alone, truth)
    ok = _correct(depth, truth)
    valid = depth > 0
    err = np.abs(depth[valid].astype(np.float64) - truth[valid])
    err = err[np.isfinite(err)]
    return {"kept": float((ok & ok_alone).sum() / max(1, ok_alone.sum())),
            "false": float((valid & ~ok).mean()),
            "mae_mm": float(np.median(err)) if err.size else float("nan")}


def devices_table(out: Path, max_n: int) -> str:
    from edge.profiles import apply_update, load_profile
    from edge.runtime.room import Member, room_profile
    from edge.sensors.room_model import StaticMember, StaticRoom

    results: dict[str, dict[int, dict[str, dict]]] = {}
    lines = []
    for kind, (path, uncoded, tag) in KINDS.items():
        base = apply_update(load_profile(path), {"room": {"name": "eval", "family_size": FAMILY_SIZE,
                                                          "code_length": CODE_LENGTH}})
        members = [StaticMember(f"{tag}{k}", k) for k in range(max_n)]
        coded = room_profile(base, Member(members[0].device, 0, ""))
        plain = apply_update(coded, {"code": {"source": uncoded}})
        ucodes = {m.device: uncoded for m in members}
        res: dict[int, dict[str, dict]] = {}
        ref = {}
        for s in STACKS:
            ref[s] = {"coded": _run(coded, StaticRoom("eval", members[:1]), s, True),
                      "uncoded": _run(plain, StaticRoom("eval", members[:1], codes=ucodes), s, False)}
        for n in range(1, max_n + 1):
            acc: dict[str, list] = {"coded": [], "uncoded": [], "time-division": []}
            for s in STACKS:
                for mode, prof, room in (("coded", coded, StaticRoom("eval", members[:n])),
                                         ("uncoded", plain, StaticRoom("eval", members[:n], codes=ucodes))):
                    d, truth = _run(prof, room, s, mode == "coded")
                    acc[mode].append(_metrics(d, ref[s][mode][0], truth))
                acc["time-division"].append(_metrics(ref[s]["uncoded"][0], ref[s]["uncoded"][0], ref[s]["uncoded"][1]))
            res[n] = {m: {k: float(np.nanmean([v[k] for v in vals])) for k in vals[0]} for m, vals in acc.items()}
            print(f"{kind} N={n}: " + ", ".join(f"{m} kept {v['kept']:.3f} false {v['false']:.4f} err {v['mae_mm']:.1f}"
                                                for m, v in res[n].items()), flush=True)
        results[kind] = res
        L_un = max(1, len(uncoded))
        lines += [f"### {kind} (`{path.relative_to(ROOT)}`)", "",
                  f"frame-rate cost: coded x{CODE_LENGTH} (family of {FAMILY_SIZE}), uncoded x{L_un}, "
                  f"time-division x{L_un if L_un > 1 else ''}N (needs a sync wire)", "",
                  "| N | coded: kept / false / depth err (mm) | uncoded | time-division |", "|---|---|---|---|"]
        for n, r in res.items():
            lines.append(f"| {n} | " + " | ".join(f"{r[m]['kept']:.3f} / {r[m]['false']:.4f} / {r[m]['mae_mm']:.1f}"
                                                   for m in ("coded", "uncoded", "time-division")) + " |")
        lines.append("")
    text = "\n".join(lines)
    (out / "devices.md").write_text(text + "\n")
    fig, ax = plt.subplots(2, len(results), figsize=(4.2 * len(results), 6.4), squeeze=False)
    for c, (kind, res) in enumerate(results.items()):
        ns = list(res)
        for m, style in (("coded", "o-"), ("uncoded", "s--"), ("time-division", "^:")):
            ax[0, c].plot(ns, [res[n][m]["kept"] for n in ns], style, label=m)
            ax[1, c].plot(ns, [res[n][m]["false"] for n in ns], style, label=m)
        ax[0, c].set(title=f"{kind}: own depth kept", ylim=(0, 1.02))
        ax[1, c].set(title="false detections (fraction of pixels)", xlabel="devices in the room N")
    ax[0, 0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "devices.png", dpi=90)
    plt.close(fig)
    return text


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default=str(ROOT / "docs" / "results" / "room"),
                    help="output folder (default docs/results/room)")
    ap.add_argument("--max-devices", type=int, default=8, help="largest number of devices in the room (default 8)")
    ap.add_argument("--pixels", type=int, default=2000, help="pixels of the slot-level simulation (default %(default)s)")
    ap.add_argument("--quick", action="store_true", help="code tables up to L = 12 only")
    args = ap.parse_args()
    if args.max_devices < 2:  # a room of one device has no table (it failed with an IndexError)
        raise ValueError(f"--max-devices must be >= 2, got {args.max_devices}")
    if args.pixels < 1:
        raise ValueError(f"--pixels must be >= 1, got {args.pixels}")
    out = output_dir(args.out)
    t0 = time.perf_counter()
    slots = slots_table(out, args.max_devices, args.pixels)
    devices = devices_table(out, args.max_devices)
    codes = codes_tables(out, args.quick)
    cmd = "OPENBLAS_NUM_THREADS=1 python tools/eval_room.py" + (" --quick" if args.quick else "")
    readme = [
        "# Several devices in one room", "",
        f"Made by `{cmd}` ({time.perf_counter() - t0:.0f} s on the reference machine).", "",
        "## Detectors under overlap (slot-level simulation)", "",
        f"`edge.source.room_slots`: my device sends 24 symbols (a DLP stack) spread over L = {CODE_LENGTH}; "
        "N-1 others send random on/off symbols with their family codes at random fractional offsets, "
        "drift up to 1e-3, each at most as bright as mine, noise 0.02. `joint` = `edge.source.joint` "
        "(known codes, estimated offsets, noise-derived threshold), `matched` = plain matched filter "
        "(correlation >= 0.85), `uncoded` = plain on/off, `time-division` = my slot alone (frame rate / N, sync).",
        "", "![slots](slots.png)", "", slots, "",
        "## Device kinds in the room simulator", "",
        "`edge.sensors.room_model` (each device's light with its room-clock offset, drift, power <= own and its "
        "own emitter position). kept = of the pixels the device alone measures correctly (within 5 % of the "
        "ground truth), the fraction still correct with the others running; false = fraction of pixels with "
        "a wrong depth (> 5 % off, or where no surface is); depth err = median |depth - ground truth| over "
        "valid pixels (mm); time-division = the uncoded device alone. Coded light curtains and event dots use the plain matched filter, "
        "coded DLP the joint filter.", "", "![devices](devices.png)", "", devices, "",
        codes]
    (out / "README.md").write_text("\n".join(readme) + "\n")
    print((out / "README.md").read_text())
    return 0


if __name__ == "__main__":
    from edge.cli import tool_main

    raise SystemExit(tool_main(main, __file__))
