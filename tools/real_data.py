"""Where the real captures beside the repository are, for the tools and the tests: one place.

The data sit in ``../shared`` next to the repository root, or under the folder named by the
``EDGE_SHARED_DIR`` environment variable.  ``procam-graycode`` holds real Gray-code captures from
a real projector and camera (OpenCV GrayCodePattern layout, 1024 x 768 projector) and their
calibration; its README gives OpenCV's own coverage figures.  Tools and tests that use these paths
skip their real-data part where the folder is absent.
"""

from __future__ import annotations

import os
from pathlib import Path

#: The repository root.
ROOT = Path(__file__).resolve().parents[1]
#: The shared data folder: $EDGE_SHARED_DIR, else ``../shared`` beside the repository.
SHARED = Path(os.environ.get("EDGE_SHARED_DIR", ROOT / ".." / "shared"))
#: The real procam dataset.
PROCAM = SHARED / "data" / "procam-graycode"
#: Its first capture (gray-10 pattern + inverse frames, white and black; 1024 x 1280 camera).
REAL_CAPTURE = PROCAM / "capture_0"
#: Its camera / projector calibration (OpenCV FileStorage XML).
CALIBRATION = PROCAM / "calibration_result.xml"
