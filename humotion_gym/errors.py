"""Exceptions raised by humotion_gym."""

from __future__ import annotations

from pathlib import Path


class MocapFormatError(ValueError):
    """A motion-capture file does not follow its format.

    The message always names the file, the line (1-based, when one line is at
    fault) and what was expected there.

    Attributes:
        path: The file that failed to parse.
        line: The 1-based line number at fault, or None for the file as a whole.
        reason: What was wrong and what was expected.
    """

    def __init__(self, path: str | Path, line: int | None, reason: str) -> None:
        self.path = str(path)
        self.line = line
        self.reason = reason
        where = f"{self.path}, line {line}" if line is not None else self.path
        super().__init__(f"{where}: {reason}")


class RigError(ValueError):
    """A skeleton's joints cannot be mapped onto the cone body's keypoints."""
