"""Figures are written whole or not at all, at the path asked for (``_plotting.save``)."""

from __future__ import annotations

import pytest

pytest.importorskip("matplotlib", reason="the report's figures need matplotlib")

from baselines.experiments._plotting import pyplot, save


def test_a_figure_cut_short_leaves_no_file(tmp_path, monkeypatch):
    """A Ctrl-C while writing left a 132-byte PNG where the report links one."""
    plt = pyplot()
    fig = plt.figure()
    target = tmp_path / "error_over_frames.png"

    def cut(path, **kwargs):
        with open(path, "wb") as fh:
            fh.write(b"\x89PNG\r\n")
        raise KeyboardInterrupt

    monkeypatch.setattr(fig, "savefig", cut)
    with pytest.raises(KeyboardInterrupt):
        save(fig, target)
    assert list(tmp_path.iterdir()) == []
    fig = plt.figure()
    assert save(fig, target) == target and target.read_bytes()[:4] == b"\x89PNG"
    assert [p.name for p in tmp_path.iterdir()] == ["error_over_frames.png"]


def test_a_name_without_a_suffix_gets_a_png_there_and_a_suffix_its_format(tmp_path):
    plt = pyplot()
    assert save(plt.figure(), tmp_path / "curve").read_bytes()[:4] == b"\x89PNG"
    assert save(plt.figure(), tmp_path / "curve.PDF").read_bytes()[:5] == b"%PDF-"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["curve", "curve.PDF"]
