"""Helpers shared by the evaluations: matplotlib without a display, markdown tables, settings as a profile.

`pyplot()` returns ``matplotlib.pyplot`` on the Agg backend (PNG files, no display);
`save_figure` writes a figure and closes it; `markdown_table` formats rows; `profile_sections`
writes the decoder settings an evaluation runs as the ``[decoder]`` / ``[camera]`` sections of
a firmware profile (so that `edge.decode.settings.from_profile` gives the same settings back).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Iterable

from ..decode.settings import DecodeSettings


def pyplot() -> Any:
    """``matplotlib.pyplot`` with the Agg (file-only) backend."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save_figure(fig: Any, path: Path, *, dpi: int) -> None:
    """Write ``fig`` to ``path`` (PNG at ``dpi``) and close it."""
    import matplotlib.pyplot as plt

    fig.savefig(path, dpi=dpi)
    plt.close(fig)


def markdown_table(header: Iterable[str], rows: Iterable[Iterable[Any]]) -> list[str]:
    """Markdown table lines: ``| a | b |``, ``|---|---|``, then one line per row (cells as str)."""
    head = list(header)
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    lines += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return lines


def profile_sections(settings: DecodeSettings) -> dict[str, dict[str, Any]]:
    """``{"decoder": {...}, "camera": {"sigma_r", "sigma_s"}}``: ``settings`` as profile sections.

    Every `DecodeSettings` field but the noise goes to ``[decoder]``; the noise model is the
    camera's (``[camera] sigma_r / sigma_s``), as `edge.decode.settings.from_profile` reads it.
    """
    values = settings.as_dict()
    camera = {"sigma_r": values.pop("sigma_r"), "sigma_s": values.pop("sigma_s")}
    return {"decoder": values, "camera": camera}
