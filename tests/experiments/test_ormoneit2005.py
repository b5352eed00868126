"""Cycle lengths of Ormoneit, Black, Hastie & Kjellström (2005): eq. 3 against the feet."""

from __future__ import annotations

import json

import numpy as np
import pytest

from baselines.cli import main
from baselines.experiments import ormoneit2005
from humotion_gym.mocap.export import write_motion_bvh
from humotion_gym.mocap.library import synthetic_library


@pytest.fixture(scope="module")
def synthetic_walks():
    return [m for m in synthetic_library() if m.label == "walk"]


@pytest.mark.mocap
def test_cycle_lengths_agree_with_the_feet_on_real_walking(real_library):
    walks = [m for m in real_library.filter(labels=["walk"]) if m.subject == "cmu-07"]
    walks += [m for m in real_library.filter(labels=["walk"]) if m.dataset == "bandai-2"][::8]
    rows = ormoneit2005.cycle_lengths(walks)
    rel = np.array([r.relative_difference for r in rows])
    assert np.isfinite(rel).all()
    assert np.median(rel) < 0.03 and rel.max() < 0.1


def test_cycle_lengths_and_the_period_command(synthetic_walks, tmp_path, capsys):
    rows = ormoneit2005.cycle_lengths(synthetic_walks)
    rel = np.array([r.relative_difference for r in rows])
    assert np.all(rel < 0.1)
    m = synthetic_walks[0]
    path = tmp_path / "walk_01.bvh"
    write_motion_bvh(path, m.params, m.shape, m.fps)
    assert main(["pca", "period", str(path), "--json", "--all-labels"]) == 0
    row = json.loads(capsys.readouterr().out.strip().splitlines()[0])
    assert row["frames_snr"] == pytest.approx(rows[0].frames_snr, abs=1.0)
    assert row["seconds_feet"] == pytest.approx(row["frames_feet"] / 30.0, abs=1e-3)
