"""Zenoh sink of the service: depth, error probability (where the decoder estimates it), confidence
and status through `edge.io.zenoh.DepthPublisher`.

Config updates arriving on ``sl/<device>/config`` go to `Service.update_config` (validated; only
the live tables may change; on any error the reply is ``config update rejected: <reason>`` and the
running profile is kept).  The header ``sequence`` is the sink's depth-map counter (0, 1, 2...);
``stack`` is the stack id, ``timestamp_ns`` the time of the stack's last camera frame.  With
``[points] publish`` (default) every depth map's point cloud goes to ``sl/<device>/points``.
"""

from __future__ import annotations

from typing import Any

from edge.runtime.result import DepthResult


class ZenohSink:
    """Publishes every `DepthResult` and status dict.  ``service`` may be None (replay --publish)."""

    def __init__(self, profile, service: Any = None, *, session: Any = None) -> None:
        from edge.io.zenoh import DepthPublisher

        from edge.io.ros import frame_ids

        on_update = service.update_config if service is not None else _reject_updates
        on_reject = getattr(service, "count_config_rejection", None)  # rejections of the zenoh layer
        self.profile = profile
        self.publisher = DepthPublisher(profile, on_update=on_update, on_reject=on_reject, session=session)
        self.frame_id = frame_ids(profile.zenoh.device)["optical"]
        self.sequence = 0

    def on_result(self, result: DepthResult) -> None:
        self.publisher.publish_depth(result.depth_mm, result.confidence, timestamp_ns=result.timestamp_ns,
                                     sequence=self.sequence, stack=result.stack, error=result.error)
        if self.profile.points.publish:
            from edge.runtime.points import result_points

            pts = result_points(result, self.profile.geometry, self.profile.points.stride)
            self.publisher.publish_points(pts, timestamp_ns=result.timestamp_ns, sequence=self.sequence,
                                          stack=result.stack, frame_id=self.frame_id)
        self.sequence += 1

    def on_status(self, status: dict[str, Any]) -> None:
        self.publisher.publish_status(status)

    def close(self) -> None:
        self.publisher.close()


def _reject_updates(update: dict[str, Any]):
    raise ValueError("this publisher replays a recording; its configuration cannot change")
