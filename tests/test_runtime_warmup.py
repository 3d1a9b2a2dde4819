"""The warm-up's helper process (`edge.runtime.warmup.VariantHelper`): it starts only while the
profile's own pipeline is slow to warm up, runs alongside, is stopped when the warm-up ends or
stops, and exits by itself when its parent is gone; what is warmed does not depend on it."""

from __future__ import annotations

import time

import pytest

from edge.profiles import load_profile
from edge.runtime import warmup
from edge.runtime.pipelines import make_pipeline

pytestmark = pytest.mark.skipif(not warmup.VariantHelper.useful(), reason="needs 2 CPUs and fcntl")


class _Profile:
    """A stand-in for the profile's pipeline: its warm-up takes ``seconds``."""

    def __init__(self, seconds: float) -> None:
        self.seconds = seconds

    def warm_up(self) -> float:
        time.sleep(self.seconds)
        return self.seconds


@pytest.fixture
def helpers(monkeypatch):
    """The VariantHelpers warm_up_all makes; the variants' own warm-ups are instant here (the
    helper's child process is the real one)."""
    made = []
    real_init = warmup.VariantHelper.__init__

    def init(self, profile):
        real_init(self, profile)
        made.append(self)

    monkeypatch.setattr(warmup.VariantHelper, "__init__", init)
    real_warm = warmup.warm_pipeline
    monkeypatch.setattr(warmup, "warm_pipeline",
                        lambda p, edc=False: real_warm(p) if isinstance(p, _Profile) else 0.0)
    return made


def test_a_slow_profile_warm_up_gets_a_helper_that_is_stopped_at_the_end(helpers):
    profile = load_profile("sim-dlp")
    seen = {}

    class Slow(_Profile):
        def warm_up(self):
            time.sleep(1.5)
            proc = helpers[0]._proc
            seen["alive"] = proc is not None and proc.poll() is None  # running alongside
            seen["proc"] = proc
            time.sleep(0.5)
            return 2.0

    report = warmup.warm_up_all(profile, make_pipeline, Slow(0), helper_after_s=0.2)
    assert report.done and report.helper
    assert set(report.seconds) == {"profile"} | {label for label, _ in warmup.switchable_variants(profile)}
    assert seen["alive"]
    assert seen["proc"].poll() is not None  # stopped with the warm-up
    assert helpers[0]._proc is None


def test_a_fast_profile_warm_up_starts_no_helper(helpers):
    report = warmup.warm_up_all(load_profile("sim-dlp"), make_pipeline, _Profile(0.0), helper_after_s=1.0)
    time.sleep(1.2)  # past the timer: it was cancelled
    assert report.done and not report.helper
    assert helpers and helpers[0]._proc is None and helpers[0]._stopped


def test_no_helper_for_an_injected_factory_or_without_variants(helpers):
    profile = load_profile("sim-dlp")
    report = warmup.warm_up_all(profile, lambda p: make_pipeline(p), _Profile(0.5), helper_after_s=0.0)
    assert report.done and not report.helper and not helpers  # a test's factory: no real kernels to share
    report = warmup.warm_up_all(profile, make_pipeline, _Profile(0.5), variants=False, helper_after_s=0.0)
    assert report.done and not report.helper and not helpers


def test_a_stopped_warm_up_stops_its_helper(helpers):
    profile = load_profile("sim-dlp")
    report = warmup.warm_up_all(profile, make_pipeline, _Profile(1.0), helper_after_s=0.1,
                                should_stop=lambda: True)
    assert not report.done and report.helper
    assert helpers[0]._proc is None


def test_the_helper_exits_when_its_parent_closes_the_pipe(monkeypatch, tmp_path):
    """The child watches its stdin: the parent gone (the pipe closed) ends it at once, whatever it
    is compiling.  Its cache is empty, so its own work (every variant's kernels compiled from
    nothing) would take minutes, not the seconds allowed; with the watch broken this times out."""
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    helper = warmup.VariantHelper(load_profile("sim-dlp"))
    helper.start()
    proc = helper._proc
    try:
        proc.stdin.close()
        assert proc.wait(30) == 0
    finally:
        helper.stop()


def test_a_helper_stopped_before_its_timer_never_starts():
    helper = warmup.VariantHelper(load_profile("sim-dlp"))
    assert helper.stop() is False
    helper.start()
    assert helper._proc is None


def test_the_helper_is_not_useful_without_the_jit(monkeypatch):
    monkeypatch.setenv("NUMBA_DISABLE_JIT", "1")
    assert not warmup.VariantHelper.useful()


def test_the_helper_warms_hard_first_then_the_rest_last_first():
    """`helper_order`: the hard decoder (no kernel shared with a soft profile's) while the parent
    compiles the profile, then the others in the reverse of the parent's order."""
    labelled = warmup.switchable_variants(load_profile("sim-dlp"))
    labels = [label for label, _ in labelled]
    order = [label for label, _ in warmup.helper_order(labelled)]
    assert sorted(order) == sorted(labels) and order[0] == "decoder.method=hard"
    rest = [x for x in labels if x != "decoder.method=hard"]
    assert order[1:] == rest[::-1]
