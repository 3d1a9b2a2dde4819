"""numba kernels of the CPU decode backend (compiled once, cached on disk with ``cache=True``).

One module per algorithm; every search kernel takes the same leading arguments
``(frames, inverse, has_inv, white, black, scale)`` (frames / inverse (n, H, W) raw, white /
black (H, W) raw, ``scale`` to normalised units), then a `CostModel` (``model``), its path's
table structure (``tables``, a NamedTuple of arrays built once per code by `edge.decode.tables`)
and a `Band` (``band``), then the outputs: ``out_col`` (H, W, 3) int32, ``out_dist`` (H, W, 3)
float32, ``out_conf`` (H, W) float32 and, for the soft paths, ``out_stats`` (H, k) int64 per row.

* `cost`: per-sample costs, quantisation, per-pixel / 64-lane LLRs, `log_levels` (`CostModel`);
* `top3`: top-3 keys, the output writer, a pixel's candidate band (`Band`);
* `scalar`: `soft_binary`, per-pixel branch-and-bound, any binary code (`ScalarTables`);
* `nary`: `soft_nary`, brute force for q-ary codes (`NaryTables`);
* `lanes`: `soft_lanes`, weight-class search 64 pixels at a time, column-linear codes (`LaneTables`);
  with a margin it locates the second and third only within it (`BEYOND` marks one beyond);
* `band_scan`: `soft_band`, scan of a disparity band, any binary code (`ScanTables`);
* `band_fold`: `soft_band_fold`, folded Walsh-Hadamard blocks over a band, column-linear (`FoldTables`);
* `hard`: `hard_lean`, hard decisions + coset-leader table, binary linear codes (`HardTables`).

All soft paths return the same arrays bit for bit (the same quantised costs, keys and ties;
tests/test_decode.py compares them with `soft_binary` and with a brute-force reference).

Integer ranges: |y_i| <= Y_CLIP = 2**24, so costs (<= n * 2**24) fit int32 for n <= 64 (the
binary limit) and keys (cost << IDX_BITS | column) fit int64.
"""

from .band_fold import soft_band_fold
from .band_scan import BAND_NET, soft_band
from .cost import LANES, METRIC_HARD, METRIC_ML, METRIC_NORMALIZED, Y_CLIP, CostModel, log_levels
from .hard import hard_lean
from .lanes import soft_lanes
from .nary import soft_nary
from .scalar import soft_binary
from .top3 import BEYOND, IDX_BITS, IDX_MASK, NO_KEY, Band, sort_small

__all__ = [
    "BAND_NET", "BEYOND", "IDX_BITS", "IDX_MASK", "LANES", "METRIC_HARD", "METRIC_ML", "METRIC_NORMALIZED", "NO_KEY", "Y_CLIP",
    "Band", "CostModel", "hard_lean", "log_levels", "soft_band", "soft_band_fold", "soft_binary", "soft_lanes",
    "soft_nary", "sort_small",
]
