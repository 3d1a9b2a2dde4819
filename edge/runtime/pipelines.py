"""The pipeline protocol and the registry that builds a profile's pipeline.

A pipeline turns one complete stack into one `edge.runtime.result.DepthResult`::

    pipeline = make_pipeline(profile)          # the class of the profile's kind (edge.device.PIPELINES)
    pipeline.schedule                          # int64 (frames_per_stack,) projector frame ids it expects
    pipeline.warm_up()                         # compile / prepare before capture; returns seconds
    pipeline.process(stack, masked_capture)    # -> DepthResult (masked_capture: EDC re-capture or None)
    pipeline.on_frame                          # optional: None or a capture hook (index, frame) that the
                                               # service's assembler calls per accepted frame (the CUDA
                                               # backend's uploads during capture, `DepthPipeline`)

The kinds (columns, dots, event-dots, curtain) and their classes are registered in one table,
`edge.device.PIPELINES`, which the sensors read too (the stack layout of a kind); the classes are
named there as ``"module:Class"`` and imported here on first use, so the registry sits below the
pipelines it names.  Adding a pipeline kind = its module in ``edge/runtime/`` (a class with
``__init__(profile)`` and the three members above) + one line in `edge.device.PIPELINES`.
"""

from __future__ import annotations

import importlib
from typing import Any, Protocol, runtime_checkable

import numpy as np

from edge.device import PIPELINES, pipeline_kind  # noqa: F401  (re-exported)

from .assembly import Stack
from .result import DepthResult, MaskedCaptureFn


@runtime_checkable
class Pipeline(Protocol):
    """One profile's processing chain.  Build once; call `process` from ONE thread (numba kernels)."""

    profile: Any
    schedule: np.ndarray

    def warm_up(self) -> float:
        """Prepare (compile kernels, build references) before the first stack; returns seconds."""
        ...

    def process(self, stack: Stack, masked_capture: MaskedCaptureFn | None = None) -> DepthResult:
        """Depth for one complete stack whose frames follow `schedule`."""
        ...


def pipeline_class(kind: str) -> type:
    """The class registered for pipeline ``kind`` (ValueError naming the known kinds)."""
    spec = PIPELINES.get(kind)
    if spec is None:
        raise ValueError(f"unknown pipeline kind {kind!r}; expected one of {', '.join(PIPELINES)}")
    module, _, name = spec.target.partition(":")
    return getattr(importlib.import_module(module), name)


def make_pipeline(profile) -> Pipeline:
    """The processing chain for ``profile``: the class of its pipeline kind (`edge.device.pipeline_kind`)."""
    return pipeline_class(pipeline_kind(profile))(profile)
