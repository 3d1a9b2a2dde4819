"""Shared helpers for the runtime/service tests (not collected: no test_ prefix)."""

from __future__ import annotations

import signal
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from edge.codes.words import pack_words
from edge.runtime.pipeline import DepthPipeline

DATA = Path(__file__).parent / "data"
TEST_PROFILE = DATA / "profiles" / "test-small.toml"


def load_test_profile(**updates):
    from edge.profiles import apply_update, load_profile

    p = load_profile(TEST_PROFILE)
    return apply_update(p, updates) if updates else p


def hard_decode_numpy(frames, white, black, code):
    """Reference hard decoder (plain numpy): threshold at (white + black) / 2, nearest codeword."""
    f = frames.astype(np.float32)
    thr = (white.astype(np.float32) + black.astype(np.float32)) / 2
    bits = (f > thr[None]).astype(np.uint8)  # (n, H, W)
    n, h, w = bits.shape
    words = pack_words(bits.reshape(n, -1).T)  # (H*W,)
    book = pack_words(code.codebook)
    dist = np.bitwise_count(words[:, None] ^ book[None, :]).astype(np.int32)
    best = np.argmin(dist, axis=1)
    d1 = dist[np.arange(dist.shape[0]), best]
    column = best.reshape(h, w).astype(np.int32)
    conf = np.clip(1.0 - d1.reshape(h, w) / (code.d_min / 2.0), 0, 1).astype(np.float32)
    valid = d1.reshape(h, w) < code.d_min / 2.0
    return SimpleNamespace(column=np.where(valid, column, -1), confidence=conf, valid=valid)


class NumpyPipeline(DepthPipeline):
    """DepthPipeline with the plain-numpy hard decoder (no dependence on edge.decode)."""

    delay_s = 0.0

    def decode(self, codes, white, black):
        if self.delay_s:
            time.sleep(self.delay_s)
        return hard_decode_numpy(codes, white, black, self.code)


def slow_pipeline(delay_s: float):
    class Slow(NumpyPipeline):
        pass

    Slow.delay_s = delay_s
    return Slow


def interactive_signals() -> None:
    """``preexec_fn`` of a service under test: SIGINT and SIGHUP at their defaults in the child,
    as an interactive shell starts a command.  A test run started under nohup or as a background
    job passes SIG_IGN on for them, and `edge run` respects an inherited SIG_IGN, so a signal
    test would otherwise depend on how pytest itself was started."""
    for sig in (signal.SIGINT, signal.SIGHUP):
        signal.signal(sig, signal.SIG_DFL)


def small_event_profile(**extra):
    """event-dots at 160x120 (same optics scaled by 1/4) so the event tests stay fast."""
    from edge.profiles import apply_update, load_profile

    p = load_profile("event-dots")
    update = {"camera": {"width": 160, "height": 120}, "projector": {"width": 160, "height": 120},
              "geometry": {"focal_px": 125.0, "cx_camera": 80.0, "cx_projector": 80.0, "cy": 60.0},
              "decoder": {"min_disparity": 1, "max_disparity": 32}}
    for k, v in extra.items():
        update.setdefault(k, {}).update(v)
    return apply_update(p, update)

