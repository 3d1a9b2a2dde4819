"""EDC evaluation: error-map ROC and adaptive loop vs Gupta et al. 2011 on simulated GI scenes.

Usage: python tools/eval_edc.py [--out docs/results/edc] [--width 256 --height 192 --seed 0 --rounds 3]
"""

from __future__ import annotations

import argparse
from pathlib import Path

from edge.commands._args import output_dir
from edge.eval.edc import GI_SCENES, check_gi_size, run_report


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", type=Path, default=Path(__file__).resolve().parents[1] / "docs" / "results" / "edc",
                   help="output folder (default docs/results/edc)")
    p.add_argument("--width", type=int, default=256, help="scene width in pixels (default 256)")
    p.add_argument("--height", type=int, default=192, help="scene height in pixels (default 192)")
    p.add_argument("--seed", type=int, default=0, help="noise seed (default 0)")
    p.add_argument("--rounds", type=int, default=3, help="adaptive EDC rounds allowed (default 3)")
    a = p.parse_args(argv)
    cmd = "python tools/eval_edc.py" + "".join(
        f" --{k} {v}" for k, v in (("width", a.width), ("height", a.height), ("seed", a.seed), ("rounds", a.rounds))
        if v != p.get_default(k))
    check_gi_size(list(GI_SCENES), a.width, a.height)  # the scene generators' own rule, as `edge edc eval`
    if a.seed < 0:
        raise ValueError(f"--seed must be >= 0, got {a.seed}")
    if a.rounds < 1:
        raise ValueError(f"--rounds must be >= 1, got {a.rounds}")
    run_report(output_dir(a.out), width=a.width, height=a.height, seed=a.seed, rounds=a.rounds, command=cmd)
    print((a.out / "README.md").read_text())
    return 0


if __name__ == "__main__":
    from edge.cli import tool_main

    raise SystemExit(tool_main(main, __file__))
