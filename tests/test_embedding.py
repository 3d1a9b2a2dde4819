"""The README's embedding snippet (Service with sensors and sinks from Python) runs as written."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _snippet() -> str:
    text = (ROOT / "README.md").read_text()
    m = re.search(r"<!-- embedding-snippet -->\s*```python\n(.*?)```", text, re.S)
    assert m, "README.md has no <!-- embedding-snippet --> python block"
    return m.group(1)


def test_readme_embedding_snippet_runs(tmp_path):
    code = _snippet()
    assert "Service(" in code and "sinks=" in code
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env, capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    lines = proc.stdout.strip().splitlines()
    assert len([ln for ln in lines if ln.startswith("stack ")]) == 3, proc.stdout
    decoded, fx, written = lines[-1].split()
    assert decoded == "3" and float(fx) == 560.0 and int(written) == 3
    assert (tmp_path / "out.mcap").stat().st_size > 0
