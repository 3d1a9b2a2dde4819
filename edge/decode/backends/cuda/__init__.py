"""The CUDA backend (numba-cuda): the exact top-3 search, hard decoding, the level refit, the
valid mask and the "error" validity rule on an NVIDIA GPU, with the CPU backend's results (bit
for bit where the CPU path is exact; the error rule's probabilities to float rounding on a GPU).

Implements the backend seam of `edge.decode.backends` (``search``, ``hard``) plus
``decode_whole`` (levels, search and valid mask on the device, used by `edge.decode.decode`
for backend "cuda"; ``outputs=`` downloads only some `Decoded` fields), `FrameStager` (pinned
host buffer sets with a stream each, keyed by stack id: the service's capture thread uploads
each frame as it arrives, its decode thread decodes the staged set) and `Staging` (the same
buffers for stacks that arrive whole).

Files by algorithm: `cost` (the shared device-side cost model), `soft` (top-3 over all
codewords / over a disparity band), `nary` (N-ary codes), `hard` (syndrome decoding),
`refit` (level self-calibration), `validity` (valid mask, spatial support), `posterior` (the
"error" validity rule: split levels, noise-fit stats, posterior, gain histogram), `device` (device
stacks, tables, launches), `pipeline` (whole decodes on the device), `staging`.

Needs the ``numba-cuda`` package (``pip install 'edge[gpu]'``); importing this module raises
ImportError without it.  Under ``NUMBA_ENABLE_CUDASIM=1`` the kernels run on numba-cuda's CPU
simulator (slow: tests use tiny images).
"""

from __future__ import annotations

import functools
import importlib.util

if importlib.util.find_spec("numba_cuda") is None:  # numba's own numba.cuda is deprecated
    raise ImportError("backend 'cuda' needs the numba-cuda package (pip install 'edge[gpu]')")

import time  # noqa: E402

import numpy as np  # noqa: E402
from numba import cuda  # noqa: E402

from ....numba_cache import install as _install_cache_lock  # noqa: E402

_install_cache_lock()  # numba-cuda's own cache file class, now that it is imported (edge.numba_cache)

from ....codes import Code  # noqa: E402
from ....capture import CodedCapture  # noqa: E402
from .cost import SIM  # noqa: E402
from .device import DeviceStack, hard_device, search_device, upload  # noqa: E402

__all__ = ["SIM", "DeviceStack", "FrameStager", "Staging", "decode_whole", "hard", "is_available", "search",
           "staging_for", "upload", "why_unavailable"]


def is_available() -> bool:
    """True when kernels can run: a CUDA device is present and numba-cuda can compile for it,
    or the simulator is enabled (`why_unavailable`)."""
    return why_unavailable() is None


def why_unavailable() -> str | None:
    """None where kernels can run, else why not, in one line: no device, a broken driver, or a
    numba-cuda that cannot compile in this environment (`_compiler_problem`)."""
    try:
        if not cuda.is_available():
            return "no CUDA device available here"
    except Exception as e:  # noqa: BLE001 - a broken driver install reads as "no device"
        return f"no CUDA device available here (the driver failed: {type(e).__name__}: {e})"
    return None if SIM else _compiler_problem()


@functools.cache
def _compiler_problem() -> str | None:
    """Why numba-cuda cannot compile kernels in this environment, or None where it can.

    Probes once per process by importing ``numba.cuda.cudaimpl`` (numba-cuda's lowering, which
    the first kernel compile imports): numba-cuda 0.30.4 under numpy 2.5, for one, fails there
    (``numpy`` has no ``row_stack``), and then every kernel fails on a machine whose device is
    fine."""
    try:
        importlib.import_module("numba.cuda.cudaimpl")
    except Exception as e:  # noqa: BLE001 - any failure there fails every kernel compile
        import numba_cuda

        return (f"numba-cuda {getattr(numba_cuda, '__version__', '?')} cannot compile kernels with numpy "
                f"{np.__version__} ({type(e).__name__}: {e}); the gpu extra pins numpy < 2.5")
    return None


def _host(cand, dist, conf, st, t0: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict]:
    """Results on the host; stats["seconds"] = upload + kernels + download (launches are async)."""
    out = (cand.copy_to_host(), dist.copy_to_host(), conf.copy_to_host())
    st["seconds"] = time.perf_counter() - t0
    return (*out, st)


def search(stack: CodedCapture, code: Code, *, metric: int, sigma_r: float, sigma_s: float, columns: int,
           band: tuple[bool, int, int], stripe: int, path: str | None = None, margin: float | None = None):
    """Exact top-3 search on the GPU (see `edge.decode.backends`): one upload, one download.

    path (binary codes): "all" or "band" (`device.search_device`); None picks one.  margin: not
    used (the exact top three meet its contract, `edge.decode.backends`)."""
    t0 = time.perf_counter()
    ds = upload(stack)
    cand, dist, conf, st = search_device(ds, code, metric=metric, sigma_r=sigma_r, sigma_s=sigma_s,
                                         columns=columns, band=band, stripe=stripe, path=path)
    return _host(cand, dist, conf, st, t0)


def hard(stack: CodedCapture, code: Code, *, columns: int, band: tuple[bool, int, int], stripe: int):
    """Hard decisions, nearest codeword in Hamming distance, on the GPU (see `edge.decode.backends`)."""
    t0 = time.perf_counter()
    ds = upload(stack)
    cand, dist, conf, st = hard_device(ds, code, columns=columns, band=band, stripe=stripe)
    return _host(cand, dist, conf, st, t0)


def __getattr__(name: str):
    # the whole-decode pipeline and the staging class import the decoder's settings lazily
    if name == "decode_whole":
        from .pipeline import decode_whole

        return decode_whole
    if name in ("FrameStager", "Staging", "staging_for"):
        from . import staging

        return getattr(staging, name)
    raise AttributeError(name)
