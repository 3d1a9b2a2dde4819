"""The service runtime: stack assembly, bounded queue, decode, depth, publish, record.

    from edge.runtime import Service, DepthPipeline, column_to_depth_mm
    service = Service(profile, open_sensor(profile), sinks=[...], recorder=RecordingThread(...))
    status = service.run(stacks=10)

Modules: `assembly` (frames -> complete stacks, drop + count incomplete), `stack_queue`
(drop-oldest hand-over), `pipelines` (the pipeline protocol and `make_pipeline`, kinds registered
in `edge.device.PIPELINES`), `result` (`DepthResult`), `pipeline` (coded columns: stack -> depth,
pure), `depth` (column -> depth mm, pure),
`dots` (dot projector: frame and event cameras), `curtain` (light curtain), `event_record` (raw
events in MCAP), `service` (threads, status, config updates), `recording` (MCAP writer thread), `replay`
(bit-exact offline replay), `console` (CLI output).
"""

from .assembly import AssemblyCounters, Stack, StackAssembler
from .depth import column_to_depth_mm, column_to_disparity, confidence_to_u8, disparity_to_depth_mm
from edge.device import DeviceModel, pipeline_kind, profile_layout, profile_schedule, stack_layout

from .pipeline import DepthPipeline
from .pipelines import Pipeline, make_pipeline
from .result import DepthResult
from .service import ConfigRejected, Service
from .stack_queue import LatestQueue

__all__ = [
    "AssemblyCounters", "ConfigRejected", "DepthPipeline", "DepthResult", "DeviceModel", "Pipeline", "LatestQueue", "Service", "Stack",
    "StackAssembler", "column_to_depth_mm", "column_to_disparity", "confidence_to_u8", "disparity_to_depth_mm",
    "make_pipeline", "pipeline_kind", "profile_layout", "profile_schedule", "stack_layout",
]
