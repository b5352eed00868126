"""The report's figures are written whole or not at all."""

from __future__ import annotations

import pytest

pytest.importorskip("matplotlib", reason="the report's figures need matplotlib")

from baselines.leaderboard.figures import _pyplot, _save


def test_a_figure_cut_short_leaves_no_file(tmp_path, monkeypatch):
    """A Ctrl-C while writing left a 132-byte PNG where the report links one."""
    plt = _pyplot()
    fig = plt.figure()
    target = tmp_path / "error_over_frames.png"

    def cut(path, **kwargs):
        with open(path, "wb") as fh:
            fh.write(b"\x89PNG\r\n")
        raise KeyboardInterrupt

    monkeypatch.setattr(fig, "savefig", cut)
    with pytest.raises(KeyboardInterrupt):
        _save(plt, fig, target)
    assert list(tmp_path.iterdir()) == []
    fig = plt.figure()
    assert _save(plt, fig, target) == target and target.read_bytes()[:4] == b"\x89PNG"
    assert [p.name for p in tmp_path.iterdir()] == ["error_over_frames.png"]
