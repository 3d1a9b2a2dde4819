"""Console output of `edge run`: one line per depth map (or a tqdm bar) and a final summary."""

from __future__ import annotations

import sys
from typing import Any, TextIO

import numpy as np

from .result import DepthResult


class ConsoleSink:
    """Prints ``stack <id>: valid <f>%, median <mm> mm, decode <ms> ms, latency <ms> ms`` per result,
    or drives a tqdm bar (``bar=True``, total = expected stacks).  Keeps running summaries."""

    def __init__(self, *, bar: bool = False, total: int | None = None, stream: TextIO | None = None,
                 quiet: bool = False) -> None:
        self.stream = stream or sys.stdout
        self.quiet = quiet
        self._bar = None
        if bar and not quiet:
            from tqdm import tqdm

            self._bar = tqdm(total=total, unit="depth", file=sys.stderr)
        self.valid: list[float] = []
        self.median_mm: list[float] = []

    def on_result(self, result: DepthResult) -> None:
        import time

        valid = result.valid_fraction
        med = result.median_depth_mm()
        self.valid.append(valid)
        self.median_mm.append(med)
        latency_ms = (time.time_ns() - result.received_ns) / 1e6
        if self._bar is not None:
            self._bar.update(1)
            self._bar.set_postfix(valid=f"{valid:.0%}", median_mm=f"{med:.0f}")
        elif not self.quiet:
            print(f"stack {result.stack:5d}: valid {100 * valid:5.1f}%  median {med:7.1f} mm  "
                  f"decode {1e3 * result.decode_s:7.1f} ms  latency {latency_ms:7.1f} ms"
                  + (f"  edc rounds {result.edc_rounds}" if result.edc_rounds else ""),
                  file=self.stream, flush=True)

    def on_status(self, status: dict[str, Any]) -> None:
        pass

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None


def summary_lines(status: dict[str, Any], console: ConsoleSink | None = None) -> list[str]:
    """Final human summary of a run from the service status (and the console's per-stack values)."""
    lines = []
    if console is not None and console.valid:
        med = np.array(console.median_mm, dtype=np.float64)
        med = med[np.isfinite(med)]
        lines.append(f"depth maps: {len(console.valid)}, valid fraction mean {np.mean(console.valid):.3f}, "
                     f"median depth {float(np.median(med)) if med.size else float('nan'):.1f} mm")
    lat50, lat99 = status.get("latency_ms_p50"), status.get("latency_ms_p99")
    lines.append(
        f"fps {status['fps']:.2f} depth/s, latency p50 {lat50 if lat50 is not None else float('nan'):.1f} ms "
        f"p99 {lat99 if lat99 is not None else float('nan'):.1f} ms, decode p50 "
        f"{status['decode_ms_p50'] if status['decode_ms_p50'] is not None else float('nan'):.1f} ms")
    lines.append(
        f"stacks: complete {status['stacks_complete']}, decoded {status['stacks_decoded']}, dropped "
        f"{status['stacks_dropped']} (stale {status['stacks_dropped_stale']}, incomplete "
        f"{status['stacks_dropped_incomplete']}; sequence gaps {status['sequence_gaps']}, out of order "
        f"{status['out_of_order']})")
    noise = status.get("noise_model")
    if noise:
        lines.append(f"noise model (last stack): sigma_r {noise['sigma_r']:.4g}, sigma_s {noise['sigma_s']:.4g} of full "
                     f"scale, " + ("fitted to the capture" if noise["fitted"] else "the profile's (not fitted)")
                     + (f"; {status['noise_fit_fallbacks']} stacks not fitted" if status.get("noise_fit_fallbacks")
                        else ""))
    if status.get("recorder"):
        r = status["recorder"]
        lines.append("recording: " + ", ".join(f"{k} {v}" for k, v in r.items() if v != ""))
    if status.get("errors"):
        lines.append(f"last error: {status['errors']}")
    return lines
