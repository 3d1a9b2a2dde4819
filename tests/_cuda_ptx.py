"""Compile every CUDA kernel of the backend to PTX with NVVM (no GPU needed) and report, per
kernel, whether the PTX holds fused multiply-adds (it must not: the CPU does not fuse).

    python tests/_cuda_ptx.py      # prints one JSON object per kernel
"""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402
from numba import cuda, types, typeof  # noqa: E402

import importlib  # noqa: E402

hard, nary, post, refit, soft, validity = (importlib.import_module(f"edge.decode.backends.cuda.{m}")
                                           for m in ("hard", "nary", "posterior", "refit", "soft", "validity"))

CC = (9, 0)


class _Target:
    """Stand-in for the current device when there is none: device functions are compiled for
    the compute capability they would get on an H100/H200 (the only thing asked of it)."""

    compute_capability = CC


def _no_device_compile() -> None:
    import numba.cuda.dispatcher as dispatcher

    try:
        cuda.get_current_device()
    except Exception:
        dispatcher.get_current_device = lambda: _Target()
u8_3 = typeof(np.zeros((1, 1, 1), np.uint8))
f32_3 = typeof(np.zeros((1, 1, 1), np.float32))
u8_2 = typeof(np.zeros((1, 1), np.uint8))
f32_2 = typeof(np.zeros((1, 1), np.float32))
f64_1 = typeof(np.zeros(1, np.float64))
f64_3 = typeof(np.zeros((1, 1, 1), np.float64))
i64_1 = typeof(np.zeros(1, np.int64))
i32_1 = typeof(np.zeros(1, np.int32))
i32_2 = typeof(np.zeros((1, 1), np.int32))
i32_3 = typeof(np.zeros((1, 1, 1), np.int32))
f32_3o = typeof(np.zeros((1, 1, 3), np.float32))
f32_1 = typeof(np.zeros(1, np.float32))
b_2 = typeof(np.zeros((1, 1), np.bool_))
f64_2 = typeof(np.zeros((1, 1), np.float64))
u64_1 = typeof(np.zeros(1, np.uint64))
B, F64, I64, F32 = types.boolean, types.float64, types.int64, types.float32

SEARCH = (u8_3, u8_3, B, u8_2, u8_2, F64, I64, F64, F64, F64, I64, f64_1, f64_3, i64_1, I64)
KERNELS = {
    "soft.full(ngroups=6)": (soft.full_kernel(6)[0], SEARCH + (B, I64, I64, I64, i32_3, f32_3o, f32_2)),
    "soft.band(ngroups=6)": (soft.band_kernel(6)[0], SEARCH + (I64, I64, I64, i32_3, f32_3o, f32_2)),
    "soft.full(ngroups=16)": (soft.full_kernel(16)[0], SEARCH + (B, I64, I64, I64, i32_3, f32_3o, f32_2)),
    "nary": (nary.soft_nary, (u8_3, u8_3, B, u8_2, u8_2, F64, I64, F64, F64, F64, I64, f64_3, u8_2, I64, B, I64,
                              I64, I64, i32_3, f32_3o, f32_2)),
    "hard.syndrome": (hard.hard_syndrome, (u8_3, u8_3, B, u8_2, u8_2, i64_1, i64_1, i64_1, i32_1, i32_1, I64, I64, B,
                                           I64, I64, I64, i32_3, f32_3o, f32_2)),
    "refit.normalise": (refit.normalise, (u8_3, u8_2, u8_2, F32, f32_3, f32_2, f32_2)),
    "refit.initial_levels": (refit.initial_levels, (f32_3, f32_2, f32_2)),
    "refit.refine_levels": (refit.refine_levels, (f32_3, f32_2, f32_2, f32_2, f32_1, f32_1, i32_3, f32_2, f32_2)),
    "validity.eligible_column": (validity.eligible_column, (i32_3, u8_2, u8_2, F32, F32, i32_2, b_2)),
    "validity.support_mask": (validity.support_mask, (i32_2, f32_2, b_2, B, F64, I64, I64, F32, F32, i32_2, b_2)),
    # the error rule's kernels without log / exp (posterior_kernel calls libdevice's log / exp, whose
    # own implementations hold FMAs: it is left out; its outputs agree with the CPU to float rounding)
    "posterior.normalise": (post.normalise, (u8_3, u8_3, B, F32, f32_3, f32_3)),
    "posterior.split_levels": (post.split_levels, (u8_3, u8_3, B, u8_2, u8_2, F64, I64, I64, f32_2, f32_2, f64_1,
                                                   f64_1)),
    "posterior.fit_stats": (post.fit_stats, (u8_3, u8_3, B, u8_2, u8_2, F64, f64_2, i32_3, I64, I64, f64_2, f64_2)),
    "posterior.gain_histogram": (post.gain_histogram, (f64_2, F64, I64, F64, i64_1)),
    "posterior.error_valid": (post.error_valid, (f64_2, f64_2, i32_3, f64_1, F64, I64, F32, f32_2, i32_2, i32_2, b_2)),
}


def _contracting(a, b, c, out):
    out[0] = a * b + c  # plain arithmetic: NVVM fuses this (the control of the FMA count)


def main() -> int:
    _no_device_compile()
    ptx, _ = cuda.compile_ptx(_contracting, (F64, F64, F64, f64_1), cc=CC)
    print(json.dumps({"kernel": "control: a * b + c", "ok": True,
                      "fma": len(re.findall(r"\bfma\.rn\.f(32|64)\b", ptx)), "ptx_lines": ptx.count("\n")}), flush=True)
    for name, (kern, sig) in KERNELS.items():
        try:
            ptx, _ = cuda.compile_ptx(kern.py_func, sig, cc=CC)
            fma = len(re.findall(r"\bfma\.rn\.f(32|64)\b", ptx))
            print(json.dumps({"kernel": name, "ok": True, "fma": fma, "ptx_lines": ptx.count("\n")}), flush=True)
        except Exception as e:  # a typing / lowering error on the real target
            print(json.dumps({"kernel": name, "ok": False, "error": f"{type(e).__name__}: {str(e)[:800]}"}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
