"""Matplotlib for the papers' figures: the file backend, and writing a figure once."""

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


def save(fig: Any, path: str | Path, dpi: int = 110) -> None:
    """Lay out ``fig``, write it to ``path`` (whole or not at all) and free it."""
    fig.tight_layout()
    try:
        write_atomically(path, lambda tmp: fig.savefig(tmp, dpi=dpi), keep_suffix=True)
    finally:
        pyplot().close(fig)
