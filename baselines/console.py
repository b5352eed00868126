"""The ``humotion-gym`` console script, ending well from its first instant.

Importing the command line (numba, scipy, OpenCV and both packages) takes
about a second; a Ctrl-C or SIGTERM in that second would end in Python's
traceback. This module imports nothing heavy itself: it takes both signals
over while the command line is imported, so that they end as at any other
moment, in one line with exit code 130 (Ctrl-C) or 143 (SIGTERM); from then
on the command runs under :func:`humotion_gym.cli.terminated_as_interrupt`.
"""

from __future__ import annotations

import os
import signal
import sys
import warnings
from types import FrameType


def _stop_while_importing(signum: int, frame: FrameType | None) -> None:
    # Nothing is written before the command line is imported: stop at once.
    word, code = ("terminated", 143) if signum == signal.SIGTERM else ("interrupted", 130)
    print(f"humotion-gym: {word}", file=sys.stderr, flush=True)
    os._exit(code)


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``humotion-gym``: :func:`baselines.cli.main`, imported inside its handling."""
    previous = {
        sig: signal.signal(sig, _stop_while_importing) for sig in (signal.SIGINT, signal.SIGTERM)
    }
    try:
        # what importing warns (numba's cache moved, say) shown as the command's warnings are
        with warnings.catch_warnings(record=True) as said:
            from baselines.cli import main as run
            from humotion_gym.cli import one_line_warning, terminated_as_interrupt
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    for w in said:
        one_line_warning(w.message, w.category, w.filename, w.lineno)
    with terminated_as_interrupt():  # the process's own: SIGTERM ends it as Ctrl-C does
        return run(argv)


if __name__ == "__main__":
    sys.exit(main())
