"""The README's quick start runs as written and records the videos it says it records.

A user's first contact is that page's two Python blocks: the random episode
recorded with ``RecordVideo``, then a baseline tracker on a test episode. They are
run here, in that order and in one namespace (the second uses the first's imports),
from a fresh folder, on the built-in default data the README's set-up gives: each
video a block's ``# writes PATH`` comment names must be there, and Gymnasium must not
warn (it does where a video folder is used twice).
"""

from __future__ import annotations

import re
import warnings
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BLOCK = re.compile(r"^```python\n(.*?)^```$", re.MULTILINE | re.DOTALL)
WRITES = re.compile(r"# writes (\S+\.mp4)")


def quick_start_blocks(readme: str) -> list[str]:
    """The Python blocks of the README's "Quick start" section, in order."""
    start = readme.index("\n## Quick start")
    end = readme.index("\n## ", start + 1)
    return BLOCK.findall(readme[start:end])


def test_the_quick_start_section_has_its_two_blocks() -> None:
    blocks = quick_start_blocks((ROOT / "README.md").read_text(encoding="utf-8"))
    assert len(blocks) == 2
    assert 'render_mode="rgb_array"' in blocks[0] and "RecordVideo(" in blocks[0]
    assert "agents.make(" in blocks[1] and "agent.predict(" in blocks[1]


def test_the_quick_start_runs_and_records_both_videos(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    pytest.importorskip("moviepy", reason="the quick start's RecordVideo needs moviepy")
    blocks = quick_start_blocks((ROOT / "README.md").read_text(encoding="utf-8"))
    monkeypatch.chdir(tmp_path)
    namespace: dict[str, object] = {"__name__": "__readme__"}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for number, block in enumerate(blocks):
            exec(compile(block, f"README.md quick start block {number + 1}", "exec"), namespace)
    assert [str(w.message) for w in caught if "WARN" in str(w.message)] == []
    printed = capsys.readouterr().out.splitlines()
    errors = [
        line for line in printed if re.fullmatch(r"error \d+ mm(, reward -?\d+\.\d\d)?", line)
    ]
    assert len(errors) >= 2 and len(errors) == len(printed)
    said = [WRITES.search(block) for block in blocks]
    assert all(said), "each block says which video it writes"
    videos = sorted(str(p.relative_to(tmp_path)) for p in tmp_path.rglob("*.mp4"))
    assert videos == sorted(match.group(1) for match in said if match)
    assert all((tmp_path / name).stat().st_size > 0 for name in videos)
