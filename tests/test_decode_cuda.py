"""The CUDA backend: bit-for-bit identity with the CPU backend and the brute-force reference.

The GPU kernels run under numba-cuda's simulator (``NUMBA_ENABLE_CUDASIM=1``) on tiny images in
a subprocess (tests/_cuda_checks.py), so the simulator never enters this process and the other
tests keep the real numba.cuda.  On a machine with a CUDA device the same checks also run at
full size (marker ``gpu``).  Without numba-cuda the backend is reported missing with one clear
error and "auto" decodes on the CPU (checked with the module hidden).
"""

from __future__ import annotations

import functools
import importlib.util
import json
import logging
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from edge.codes import get_code
from edge.decode import decode
from edge.decode.backends import available, get, resolve
from edge.decode.synthetic import make_capture

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
HAVE_NUMBA_CUDA = importlib.util.find_spec("numba_cuda") is not None
needs_numba_cuda = pytest.mark.skipif(not HAVE_NUMBA_CUDA, reason="numba-cuda is not installed (pip install 'edge[gpu]')")


@functools.lru_cache(maxsize=None)
def _has_gpu() -> bool:
    if not HAVE_NUMBA_CUDA or os.environ.get("NUMBA_ENABLE_CUDASIM") == "1":
        return False
    code = "from numba import cuda; import sys; sys.exit(0 if cuda.is_available() else 1)"
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_ENABLE_CUDASIM"}
    return subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, timeout=120).returncode == 0


def _run_checks(*args: str, sim: bool, timeout: int) -> dict[str, dict]:
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    if sim:
        env["NUMBA_ENABLE_CUDASIM"] = "1"
    else:
        env.pop("NUMBA_ENABLE_CUDASIM", None)
    proc = subprocess.run([sys.executable, str(HERE / "_cuda_checks.py"), *args], env=env, capture_output=True,
                          text=True, timeout=timeout)
    results = {}
    for line in proc.stdout.splitlines():
        if line.startswith("{"):
            rec = json.loads(line)
            if "check" in rec:
                results[rec["check"]] = rec
    if not results:
        raise AssertionError(f"the CUDA checks produced no results (rc {proc.returncode}):\n{proc.stderr[-3000:]}")
    return results


CHECKS = ["resolve-auto", "soft-all-ecc-22-10-uint8", "soft-all-gray-10-inverse",
          "soft-all-ecc-22-10-float32-normalized-columns", "soft-band-ecc-22-10-uint16",
          "soft-band-ecc-22-10-inverse-stripe", "soft-band-gray-10-bitdepth-normalized", "soft-all-restricted-to-band",
          "soft-nary3-6", "hard-metric-search-gray-10", "hard-ecc-22-10", "hard-ecc-22-10-inverse-band", "hard-gray-10",
          "validity", "refit-kernels-ecc-22-10", "refit-kernels-rs16-15-4", "decode-soft", "decode-hard",
          "decode-list+median", "decode-soft-refit", "decode-hard-refit-uint16", "decode-soft-inverse-nocheck",
          "confidence-fit-soft", "confidence-fit-soft-refit", "confidence-fit-list+median",
          "error-rule-ecc-22-10-band", "error-rule-ecc-22-10-all", "error-rule-gray-10-inverse-band",
          "error-rule-ecc-22-10-inverse-all", "error-rule-gray-10-uint16-median",
          "error-rule-ecc-22-10-hard-calibration", "error-rule-nary3-6",
          "error-rule-ecc-22-10-fitted", "error-rule-reduced-download", "error-rule-ecc-22-10-sgm",
          "staging", "runtime-pipeline", "reduced-download", "staged-frames", "staged-fallback", "staged-threads",
          "service-staged", "runtime-error-rule", "posterior-prior-ecc-22-10", "posterior-prior-ecc-22-10-inverse",
          "prior-cost"]


#: CI's budget: on a cold 2-core machine the simulator subprocess compiles every CPU reference
#: it calls that the session has not cached yet (these tests run last, `conftest.py`).  Under the
#: simulator every GPU thread is a Python thread; `_cuda_checks.yield_while_polled` keeps the
#: simulator's block loop from starving them: on the development machine (warm cache) the 21
#: checks CI ran before went from 154 s to 24 s with it, and all checks take 80 s.  CI runs
#: every check but the three slowest: "error-rule-ecc-22-10-fitted" (576 pixels, enough for the binned noise fit,
#: 16 s), "confidence-fit-soft-refit" (6 s) and "staged-threads" (6 s) run in the full set only:
#: ``EDGE_CUDA_CHECKS=full`` runs every check.
FULL_ONLY = ("error-rule-ecc-22-10-fitted", "confidence-fit-soft-refit", "staged-threads")
CI_CHECKS = [c for c in CHECKS if c not in FULL_ONLY]
RUN_CHECKS = CHECKS if os.environ.get("EDGE_CUDA_CHECKS") == "full" else CI_CHECKS


@pytest.fixture(scope="module")
def sim_results():
    if not HAVE_NUMBA_CUDA:
        pytest.skip("numba-cuda is not installed (pip install 'edge[gpu]')")
    return _run_checks(*([] if RUN_CHECKS is CHECKS else RUN_CHECKS), sim=True, timeout=600)


@needs_numba_cuda
@pytest.mark.timeout(900)
@pytest.mark.parametrize("check", RUN_CHECKS)
def test_cuda_simulator_matches_cpu(sim_results, check):
    """Every CUDA path returns the CPU backend's arrays exactly (and the brute-force reference's
    top-3 for the soft searches), under the simulator on tiny images."""
    rec = sim_results.get(check)
    assert rec is not None, f"check {check!r} did not run"
    assert rec["ok"], rec["detail"]


@pytest.mark.gpu
@pytest.mark.timeout(1800)
def test_cuda_full_size_matches_cpu():
    """The same checks at full size on a real GPU (600 x 700 all-codeword searches)."""
    if not _has_gpu():
        pytest.skip("no CUDA device here (numba-cuda reports none)")
    results = _run_checks("--full", sim=False, timeout=1700)
    bad = {k: v["detail"] for k, v in results.items() if not v["ok"]}
    assert set(CHECKS) <= set(results)
    assert not bad, bad


def _run_script(script: str) -> subprocess.CompletedProcess:
    """`script` in a fresh interpreter without the simulator (the repo on its path); asserts it
    exited 0 and returns it (stdout as text)."""
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    env.pop("NUMBA_ENABLE_CUDASIM", None)
    proc = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return proc


def _tiny():
    code = get_code("gray-10")
    rng = np.random.default_rng(0)
    cap = make_capture(code, rng.integers(0, code.size, (4, 8)), rng=rng)
    return code, cap


def test_no_device_auto_falls_back_with_a_log_line_and_cuda_is_one_clear_error(caplog):
    """Here (no GPU, no simulator in this process): "auto" decodes on the CPU and says so; "cuda"
    is one ValueError naming the backend."""
    if os.environ.get("NUMBA_ENABLE_CUDASIM") == "1" or _has_gpu():
        pytest.skip("a CUDA device (or the simulator) is present")
    code, cap = _tiny()
    with caplog.at_level(logging.INFO, logger="edge.decode"):
        assert resolve("auto") == "cpu"
    assert "decoding on the CPU" in caplog.text
    auto = decode(cap.frames, cap.white, cap.black, code, backend="auto")
    ref = decode(cap.frames, cap.white, cap.black, code)
    assert np.array_equal(auto.column, ref.column) and np.array_equal(auto.distances, ref.distances)
    assert not available("cuda")
    with pytest.raises(ValueError, match="backend 'cuda'"):
        decode(cap.frames, cap.white, cap.black, code, backend="cuda")


def test_without_numba_cuda_the_package_imports_and_cuda_is_reported_missing():
    """With numba-cuda hidden (an import blocker), edge imports, "auto" decodes on the CPU and
    backend "cuda" is one ValueError saying the package is not installed."""
    script = r"""
import sys
sys.modules["numba_cuda"] = None  # hide numba-cuda: importing it raises ImportError
import functools
import importlib.util
real = importlib.util.find_spec
importlib.util.find_spec = lambda name, *a: None if name.split(".")[0] == "numba_cuda" else real(name, *a)
import numpy as np
from edge.codes import get_code
from edge.decode import decode
from edge.decode.backends import available, get, resolve
from edge.decode.synthetic import make_capture
code = get_code("gray-10")
rng = np.random.default_rng(0)
cap = make_capture(code, rng.integers(0, code.size, (4, 8)), rng=rng)
assert not available("cuda")
assert resolve("auto") == "cpu"
d = decode(cap.frames, cap.white, cap.black, code, backend="auto")
assert (d.column >= -1).all()
try:
    get("cuda")
except ValueError as e:
    assert "not installed" in str(e) and "numba-cuda" in str(e), e
    print("OK", e)
else:
    raise SystemExit("backend 'cuda' without numba-cuda did not raise")
"""
    proc = _run_script(script)
    assert "OK backend 'cuda': not installed here" in proc.stdout


def test_a_device_numba_cuda_cannot_compile_for_is_unavailable_with_the_reason():
    """A device is present but numba-cuda's lowering fails to import (numba-cuda 0.30.4 under
    numpy 2.5, seen on an H200: every kernel then fails): "cuda" is unavailable, "auto" decodes
    on the CPU and logs why, backend "cuda" is one ValueError with the reason.  Where the
    lowering imports (this environment), the probe finds no problem."""
    if not HAVE_NUMBA_CUDA:
        pytest.skip("numba-cuda is not installed (pip install 'edge[gpu]')")
    script = r"""
import importlib, logging, io
import numpy as np
from edge.decode.backends import available, get, resolve
from edge.decode.backends import cuda as gpu
assert gpu._compiler_problem() is None, gpu._compiler_problem()  # the real probe, here
gpu._compiler_problem.cache_clear()
gpu.cuda.is_available = lambda: True  # the driver reports a device
real = importlib.import_module
def broken(name, *a):
    if name == "numba.cuda.cudaimpl":
        raise AttributeError("module 'numpy' has no attribute 'row_stack'")
    return real(name, *a)
importlib.import_module = broken
log = io.StringIO()
logging.getLogger("edge.decode").addHandler(logging.StreamHandler(log))
logging.getLogger("edge.decode").setLevel(logging.INFO)
assert not gpu.is_available() and not available("cuda")
assert "cannot compile kernels with numpy" in gpu.why_unavailable(), gpu.why_unavailable()
assert resolve("auto") == "cpu"
assert "row_stack" in log.getvalue() and "decoding on the CPU" in log.getvalue(), log.getvalue()
def refusal(name):
    try:
        get(name)
    except ValueError as e:
        return str(e)
err = refusal("cuda")  # None: backend 'cuda' with a broken numba-cuda did not raise
assert err is not None and err.startswith("backend 'cuda': numba-cuda") and "numpy < 2.5" in err, err
print("OK", err)
"""
    proc = _run_script(script)
    assert "OK backend 'cuda': numba-cuda" in proc.stdout


def test_stage_clock_reports_the_stages_in_stream_order():
    """`pipeline.StageClock` with stand-in CUDA events (no GPU here): each stage's milliseconds
    are the time between its boundary and the previous one, in the order marked; it reads the
    times only after the last event completed; under the simulator there are none."""
    if not HAVE_NUMBA_CUDA:
        pytest.skip("numba-cuda is not installed (pip install 'edge[gpu]')")
    script = r"""
from edge.decode.backends.cuda import pipeline
clock_ms = iter([0.0, 1.5, 4.0, 4.25])
synced = []
class Event:
    def record(self, stream=0):
        self.t, self.stream = next(clock_ms), stream
    def synchronize(self):
        synced.append(self.t)
    def elapsed_time(self, other):
        assert synced == [4.25], "read before the last event completed"
        return other.t - self.t
pipeline.SIM = False
pipeline.cuda.event = Event
c = pipeline.StageClock("s")
for name in ("levels", "search", "tail"):
    c.mark(name)
assert all(ev.stream == "s" for _, ev in c.marks)
assert c.stage_ms() == {"levels": 1.5, "search": 2.5, "tail": 0.25}, c.stage_ms()
pipeline.SIM = True
s = pipeline.StageClock("s")
s.mark("levels")
assert s.stage_ms() is None and s.marks == []
print("OK")
"""
    proc = _run_script(script)
    assert "OK" in proc.stdout


def test_profile_backend_reaches_the_decoder():
    """A profile's ``[decoder] backend`` is the settings' backend (what the runtime decodes with)."""
    from edge.decode.settings import DEFAULT_SETTINGS

    for name in ("cpu", "cuda", "auto"):
        assert DEFAULT_SETTINGS.replace(backend=name).backend == name
    with pytest.raises(ValueError, match="backend"):
        DEFAULT_SETTINGS.replace(backend="gpu")
    assert get("cpu").__name__.endswith(".cpu")


def test_runtime_pipeline_with_auto_backend_decodes_on_the_cpu_here():
    """A profile with ``[decoder] backend = "auto"`` decodes in the runtime exactly as "cpu" where
    there is no CUDA device (the pipeline's staging hook is not taken)."""
    if os.environ.get("NUMBA_ENABLE_CUDASIM") == "1" or _has_gpu():
        pytest.skip("a CUDA device (or the simulator) is present")
    sys.path.insert(0, str(HERE))
    from _service_helpers import load_test_profile

    from edge.runtime.pipeline import DepthPipeline

    cpu_pipe = DepthPipeline(load_test_profile())
    auto_pipe = DepthPipeline(load_test_profile(decoder={"backend": "auto"}))
    code = cpu_pipe.code
    rng = np.random.default_rng(4)
    cap = make_capture(code, rng.integers(0, code.size, (6, 32)), rng=rng)
    ref, got = cpu_pipe.decode(cap.frames, cap.white, cap.black), auto_pipe.decode(cap.frames, cap.white, cap.black)
    for f in ("column", "confidence", "valid", "candidates", "distances"):
        assert np.array_equal(getattr(ref, f), getattr(got, f)), f


@needs_numba_cuda
@pytest.mark.timeout(600)
def test_kernels_compile_for_the_gpu_without_fused_multiply_adds():
    """Every kernel compiles to sm_90 PTX with the real NVVM (no GPU needed) and none holds an
    FMA: a plain ``a * b + c`` does get fused (the control), the kernels' products do not, so the
    device rounds every product as the CPU does.  Skipped where NVVM / NVRTC are not installed."""
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    env.pop("NUMBA_ENABLE_CUDASIM", None)
    proc = subprocess.run([sys.executable, str(HERE / "_cuda_ptx.py")], env=env, capture_output=True, text=True,
                          timeout=540)
    recs = [json.loads(line) for line in proc.stdout.splitlines() if line.startswith("{")]
    missing = ("DynamicLibNotFound", "NvvmSupportError", "cannot be found", "libnvvm", "libnvrtc")
    if not recs or any(not r["ok"] and any(m in r["error"] for m in missing) for r in recs):
        pytest.skip(f"NVVM / NVRTC not installed here: {(proc.stderr or str(recs))[-300:]}")
    assert recs[0]["kernel"].startswith("control") and recs[0]["fma"] > 0, recs[0]
    bad = [r for r in recs[1:] if not r["ok"] or r["fma"] != 0]
    assert len(recs) >= 11 and not bad, bad
