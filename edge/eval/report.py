"""Helpers shared by the evaluations: matplotlib without a display, markdown tables, settings as a profile.

`pyplot()` returns ``matplotlib.pyplot`` on the Agg backend (PNG files, no display);
`save_figure` writes a figure and closes it; `markdown_table` formats rows; `profile_sections`
writes the decoder settings an evaluation runs as the ``[decoder]`` / ``[camera]`` sections of
a firmware profile (so that `edge.decode.settings.from_profile` gives the same settings back);
`poisson_interval` and `calibration_verdict` judge a reliability bin's error count against the
count its predicted probabilities expect.
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


def poisson_interval(k: int, level: float = 0.99) -> tuple[float, float]:
    """Exact (Garwood) two-sided ``level`` interval of a Poisson mean from a count k >= 0, by
    bisection (each end to 1e-12 relative)."""
    from math import exp, lgamma, log

    def cdf(k_: int, mu: float) -> float:  # P(X <= k_)
        if k_ < 0:
            return 0.0
        return sum(exp(i * log(mu) - mu - lgamma(i + 1)) for i in range(k_ + 1)) if mu > 0 else 1.0

    def solve(f, lo: float, hi: float) -> float:
        for _ in range(100):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if f(mid) else (lo, mid)
        return 0.5 * (lo + hi)

    tail = (1.0 - level) / 2.0
    top = 10.0 * (k + 10)
    low = 0.0 if k == 0 else solve(lambda mu: 1.0 - cdf(k - 1, mu) < tail, 0.0, top)
    high = solve(lambda mu: cdf(k, mu) > tail, 0.0, top)
    return low, high


def calibration_verdict(expected: float, seen: int, *, factor: float = 2.0, level: float = 0.99) -> str:
    """A reliability bin judged against "calibrated within ``factor``": "within" where the seen
    error count is within ``factor`` of the expected one (the sum of the bin's predicted
    probabilities), "consistent" where it is not but the count's ``level`` Poisson interval
    (`poisson_interval`) still reaches that band (a bin expecting 4 errors scatters by more than
    2x on its own), "off" where the count rules the band out."""
    if expected / factor <= seen <= expected * factor:
        return "within"
    low, high = poisson_interval(int(seen), level)
    return "consistent" if low <= factor * expected and high >= expected / factor else "off"


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
