"""Write the Foxglove layout for edge recordings and the live sink (docs/foxglove/edge-layout.json).

    python tools/foxglove_layout.py [--device sim-dlp] [--out docs/foxglove/edge-layout.json]

Built with foxglove-sdk's typed layout classes (``foxglove.layouts``): depth (turbo colour map,
0.2-3 m) and confidence images with the calibration topic, a 3D panel that follows the
device's ``<name>_link`` frame and shows the point cloud (coloured by z), the depth image projected
as a cloud and the frame tree, and the status as raw messages.  Topics are ``/<device>/...`` as
in `edge.io.mcap_format` and `edge.io.foxglove_sink`; for another device, rerun with
``--device``.  Import it in Foxglove with Layouts -> Import from file.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from edge.io.ros import frame_ids  # noqa: E402


def build(device: str) -> dict:
    import foxglove.layouts as fl

    t = {leaf: f"/{device}/{leaf}" for leaf in ("depth", "confidence", "calibration", "points", "tf", "status")}
    ids = frame_ids(device)

    def image(topic: str, lo: float, hi: float, title: str):
        return fl.ImagePanel(title=title, config=fl.ImageConfig(image_mode=fl.ImageModeConfig(
            image_topic=topic, calibration_topic=t["calibration"], color_mode="colormap", color_map="turbo",
            min_value=lo, max_value=hi)))

    three = fl.ThreeDeePanel(title="point cloud", config=fl.ThreeDeeConfig(
        follow_tf=ids["base"],
        topics={
            t["points"]: fl.BaseRendererPointCloudTopicSettings(
                visible=True, point_size=2, color_mode="colormap", color_field="z", color_map="turbo"),
            t["depth"]: fl.BaseRendererImageTopicSettings(
                visible=False, camera_info_topic=t["calibration"], render_mode="pointCloud"),
            t["tf"]: fl.BaseRendererBaseSettings(visible=True),
        }))
    layout = fl.Layout(content=fl.SplitContainer(direction="row", items=[
        fl.SplitItem(proportion=1, content=fl.SplitContainer(direction="column", items=[
            fl.SplitItem(proportion=1, content=image(t["depth"], 200.0, 3000.0, "depth (mm)")),
            fl.SplitItem(proportion=1, content=image(t["confidence"], 0.0, 255.0, "confidence")),
        ])),
        fl.SplitItem(proportion=2, content=fl.SplitContainer(direction="column", items=[
            fl.SplitItem(proportion=3, content=three),
            fl.SplitItem(proportion=1, content=fl.RawMessagesPanel(
                title="status", config=fl.RawMessagesConfig(topic_path=t["status"]))),
        ])),
    ]))
    return json.loads(layout.to_json())


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--device", default="sim-dlp", help="device name (profile zenoh.device; default sim-dlp)")
    ap.add_argument("--out", default=str(Path(__file__).resolve().parents[1] / "docs" / "foxglove" / "edge-layout.json"),
                    help="output JSON (default docs/foxglove/edge-layout.json)")
    args = ap.parse_args(argv)
    Path(args.out).write_text(json.dumps(build(args.device), indent=2) + "\n")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    from edge.cli import tool_main

    raise SystemExit(tool_main(main, __file__))
