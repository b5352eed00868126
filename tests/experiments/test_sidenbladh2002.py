"""Figures 3 and 4 of Sidenbladh, Black & Sigal (2002) for the tree prior."""

from __future__ import annotations

import numpy as np
import pytest

from humotion_gym.experiments import sidenbladh2002
from humotion_gym.mocap.library import synthetic_library
from humotion_gym.priors import tree


@pytest.fixture(scope="module")
def library():
    return synthetic_library()


@pytest.fixture(scope="module")
def body_prior(library):
    # Subject 1's six clips (walk, run, skip, arm swing, reach, wave), as in the tree's own tests.
    return tree.fit(library.split("train").motions[:6])


def test_fig3_spread_grows_with_beta(library, body_prior):
    test = library.split("test").motions
    walks = [m for m in test if m.label == "walk"]
    histories = np.array([m.params[t - tree.WINDOW : t + 1] for m in walks for t in (40, 120)])
    shapes = [m.shape for m in walks for _ in (40, 120)]
    spread = sidenbladh2002.next_pose_spread(
        body_prior, histories, shapes, (0.01, 0.1, 1.0), np.random.default_rng(9)
    )
    assert np.all(np.diff(spread) > 0), spread


def test_make_figures_and_cli(tmp_path, library):
    from humotion_gym.cli import build_parser
    from humotion_gym.cli import tree as tree_cli

    small = library.filter(subjects=["synthetic-01", "synthetic-05"])
    paths = sidenbladh2002.make_figures(small, tmp_path, seed=0)
    assert set(paths) == {"fig3", "fig4"}
    for path in paths.values():
        assert path.is_file() and path.read_bytes()[:4] == b"\x89PNG"
    args = build_parser().parse_args(["tree", "figures", "--out-dir", str(tmp_path), "--seed", "3"])
    assert args.func is tree_cli._cmd_figures and args.seed == 3 and args.out_dir == tmp_path
