"""Figures 3 and 4 of Sidenbladh, Black & Sigal (2002) for the tree prior."""

from __future__ import annotations

import numpy as np
import pytest

from baselines.experiments import sidenbladh2002
from baselines.priors import tree
from humotion_gym.mocap.library import synthetic_library


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
    pytest.importorskip("matplotlib", reason="its figures need matplotlib")
    from baselines.cli import build_parser
    from baselines.cli import tree as tree_cli

    small = library.filter(subjects=["synthetic-01", "synthetic-05"])
    paths = sidenbladh2002.make_figures(small, tmp_path, seed=0)
    assert set(paths) == {"fig3", "fig4"}
    for path in paths.values():
        assert path.is_file() and path.read_bytes()[:4] == b"\x89PNG"
    args = build_parser().parse_args(["tree", "figures", "--out-dir", str(tmp_path), "--seed", "3"])
    assert args.func is tree_cli._cmd_figures and args.seed == 3 and args.out_dir == tmp_path


def test_explained_variance_by_features_is_the_svd_of_each_feature_set(body_prior):
    rows = sidenbladh2002.explained_variance_by_features(body_prior, components=4, windows=500)
    assert [(r["features"], r["scaled"]) for r in rows] == [
        (f, s) for f in sidenbladh2002.FEATURE_SETS for s in (True, False)
    ]
    by = {(r["features"], r["scaled"]): r for r in rows}
    # the prior's own features: every free parameter's pose and velocity per frame
    both = by["pose+velocity", True]
    assert both["dimensions"] == by["pose", True]["dimensions"] + by["velocity", True]["dimensions"]
    assert (
        both["dimensions"]
        == body_prior.window * body_prior.components.shape[0] // body_prior.window
    )
    # an oracle: with every window sampled, the unscaled share is the SVD of the
    # prior's own centred windows (database_windows undoes nothing but Gamma)
    every = sidenbladh2002.explained_variance_by_features(
        body_prior, components=4, windows=body_prior.n_windows
    )
    x = tree.database_windows(body_prior) * np.sqrt(
        np.tile(body_prior.feature_var, body_prior.window)
    )
    power = np.linalg.svd(x - x.mean(axis=0), compute_uv=False) ** 2
    assert every[1]["explained"] == pytest.approx(power[:4].sum() / power.sum(), rel=1e-6)
    for r in rows:
        assert 0.0 < r["explained"] <= 1.0 + 1e-12
        assert 1 <= r["components_for_89"] <= r["dimensions"]
    full = sidenbladh2002.explained_variance_by_features(
        body_prior, components=both["dimensions"], windows=500
    )
    assert full[0]["explained"] == pytest.approx(1.0)
    with pytest.raises(ValueError, match="at least 1"):
        sidenbladh2002.explained_variance_by_features(body_prior, components=0)


def test_cli_tree_variance_prints_each_feature_set(capsys):
    from baselines.cli import main

    assert main(["tree", "variance", "--windows", "300"]) == 0
    out = capsys.readouterr().out
    assert "pf-tree's database" in out and out.count("\n") >= 8
    for name in sidenbladh2002.FEATURE_SETS:
        assert name in out
