"""The service core: stack assembly, bounded queue, pipelines, depth, status, config updates.

    from edge.runtime import Service, DepthPipeline, column_to_depth_mm
    service = Service(profile, open_sensor(profile), sinks=[...], recorder=RecordingThread(...))
    status = service.run(stacks=10)

Modules: `assembly` (frames -> complete stacks, drop + count incomplete), `stack_queue`
(drop-oldest hand-over), `pipelines` (the pipeline protocol and `make_pipeline`, kinds registered
in `edge.device.PIPELINES`), `result` (`DepthResult`), `pipeline` (coded columns: stack -> depth,
pure), `depth` (column -> depth mm, pure), `edc_stage` (adaptive EDC rounds of the columns
pipeline), `dots` (dot projector: frame and event cameras), `curtain` (light curtain), `service`
(threads, status, config updates), `warmup` (compile before capture), `console` (CLI output).
The sinks and the recorder are given to `Service` as objects; the ones that talk to the outside
world live in `edge.io` (`publish` zenoh, `recording` MCAP writer thread, `ros_sink`,
`foxglove_sink`, `replay` bit-exact offline replay), which imports this package, never the reverse.
"""

from edge.device import DeviceModel, pipeline_kind, profile_layout, profile_schedule, stack_layout

from .assembly import AssemblyCounters, Stack, StackAssembler
from .depth import column_to_depth_mm, column_to_disparity, confidence_to_u8, disparity_to_depth_mm
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
