#!/usr/bin/env bash
# The GPU figures and the full-size exactness checks of the CUDA backend in one run, for a
# machine with an NVIDIA GPU (numba-cuda, NVVM and NVRTC installed; the repository's checkout as
# the working directory).
#
#     tools/gpu_checks.sh [OUTDIR]          (default OUTDIR: gpu-checks)
#
# Writes, and prints as it goes:
#   OUTDIR/env.txt             the device, driver and package versions
#   OUTDIR/bench_cuda.txt      python tools/bench_decode.py --backend cuda (600 x 700 ecc-22-10:
#                              kernel only against a plain GEMM + top-3 baseline, end to end,
#                              staged, and the hard regime with decode()'s defaults)
#   OUTDIR/checks_full.jsonl   python tests/_cuda_checks.py --full (every CUDA path against the
#                              CPU backend and the brute-force reference, 600 x 700 / 120 x 160);
#                              what `pytest -m gpu tests/test_decode_cuda.py` asserts
# Time limits per step (seconds): BENCH_S (default 300), CHECKS_S (default 600).  PARALLEL=1 runs
# the checks beside the bench, each with half the CPUs' numba threads (a short lease; the bench's
# GPU timings then share the device with the checks' launches).
# Exit status: 0 when the bench's rows and every check agree with the CPU, else 1.
set -u
out=${1:-gpu-checks}
mkdir -p "$out"
export PYTHONPATH="$PWD${PYTHONPATH:+:$PYTHONPATH}" PYTHONUNBUFFERED=1
export NUMBA_CACHE_DIR="${NUMBA_CACHE_DIR:-${TMPDIR:-/tmp}/edge-gpu-checks-numba-cache}"
py=${PYTHON:-python3}

{
    date -u
    nvidia-smi --query-gpu=name,driver_version,memory.total,clocks.max.sm --format=csv 2>&1
    "$py" - <<'EOF'
import os, platform
import numba, numpy, numba_cuda
from numba import cuda
print(f"python {platform.python_version()}, numpy {numpy.__version__}, numba {numba.__version__}, "
      f"numba-cuda {numba_cuda.__version__}, {os.cpu_count()} CPUs")
d = cuda.get_current_device()
print(f"device {d.name}, compute capability {d.compute_capability}, runtime {cuda.runtime.get_version()}")
EOF
} 2>&1 | tee "$out/env.txt"

status=0
checks() { timeout "${CHECKS_S:-600}" "$py" tests/_cuda_checks.py --full > "$out/checks_full.jsonl" 2>&1; }
if [ "${PARALLEL:-0}" = 1 ]; then
    # a short lease: the checks (mostly CPU references) beside the bench, each on half the CPUs
    half=$(( $(nproc) / 2 > 0 ? $(nproc) / 2 : 1 ))
    NUMBA_NUM_THREADS=$half checks &
    checks_pid=$!
    export NUMBA_NUM_THREADS=$half
    echo "PARALLEL=1: the full-size checks run beside the bench, $half numba threads each" | tee "$out/bench_cuda.txt"
fi
timeout "${BENCH_S:-300}" "$py" tools/bench_decode.py --backend cuda 2>&1 | tee -a "$out/bench_cuda.txt"
[ "${PIPESTATUS[0]}" = 0 ] || status=1

if [ "${PARALLEL:-0}" = 1 ]; then
    wait "$checks_pid" || status=1
else
    checks || status=1
fi
cat "$out/checks_full.jsonl"
"$py" - "$out/checks_full.jsonl" <<'EOF' || status=1
import json, sys
rows = [json.loads(line) for line in open(sys.argv[1]) if line.startswith("{")]
checks = {r["check"]: r for r in rows if "check" in r}
bad = [name for name, r in checks.items() if not r["ok"]]
seconds = sum(r["seconds"] for r in rows if "timing" in r)
print(f"full-size checks: {len(checks)} ran, {len(checks) - len(bad)} agree with the CPU, failed: {bad or 'none'}"
      f" ({seconds:.0f} s)")
sys.exit(1 if bad or not checks else 0)
EOF
exit $status
