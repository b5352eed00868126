"""Matplotlib for the figures: the file backend, and writing a figure once."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from humotion_gym.files import write_atomically


def pyplot() -> Any:
    """``matplotlib.pyplot`` on the Agg backend (figures go to files, never a window).

    Imported on first use: matplotlib takes a second to import, which the
    commands' ``--help`` should not pay.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save(fig: Any, path: str | Path, dpi: int = 110, layout: bool = True) -> Path:
    """Write ``fig`` to ``path``, whole or not at all, and free it; returns ``path``.

    Every figure of both packages' reports and experiments is written here,
    laid out first (``tight_layout``) unless ``layout`` is False. The format
    is ``path``'s suffix (PNG where it has none), named to matplotlib, since
    the temporary file written first has another suffix.
    """
    path = Path(path)
    if layout:
        fig.tight_layout()
    fmt = path.suffix.lstrip(".").lower() or "png"
    try:
        write_atomically(path, lambda tmp: fig.savefig(tmp, dpi=dpi, format=fmt))
    finally:
        pyplot().close(fig)
    return path
