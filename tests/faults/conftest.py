"""tests/faults: the fault suite (issue 12).  Makes tests/_service_helpers.py and tools/ importable."""

import sys
from pathlib import Path

_HERE = Path(__file__).resolve().parent
for _p in (_HERE.parent, _HERE.parents[1] / "tools"):
    if str(_p) not in sys.path:
        sys.path.insert(0, str(_p))
