"""Figures 3 and 4 of Sidenbladh, Black & Sigal (ECCV 2002) for the tree prior.

* Fig. 3: the spread of sampled next poses grows with the temperature
  ``beta``. For a held-out walking window, 10 next poses are drawn at each of
  several temperatures and drawn as side views; a last panel gives the mean
  spread (mm, over the 15 keypoints) of 10 samples against ``beta`` for many
  held-out windows.
* Fig. 4: the distribution of the coefficients of the windows that the tree
  samples, beside the Gaussian model of eq. 3 (``N(c_t,l, beta sigma_l^2)``)
  and beside exact draws from eq. 3, for the first four coefficients.

The next poses are drawn without the transition's added noise, so the spread is
the search's alone. Command line: ``humotion-gym tree figures --out-dir DIR``
(:func:`make_figures`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from baselines.experiments._plotting import pyplot, save
from baselines.filtering import ParticleState
from baselines.priors import tree, tree_model
from humotion_gym import body
from humotion_gym.mocap.library import MotionLibrary
from humotion_gym.mocap.motion import Motion

FloatArray = NDArray[np.float64]

#: Temperatures of Fig. 3.
FIG3_BETAS: tuple[float, ...] = (0.01, 0.1, 1.0, 10.0)


def _probe_histories(
    fitted: tree.TreeParams, motions: Sequence[Motion], count: int, seed: int
) -> tuple[FloatArray, FloatArray, list[body.BodyShape]]:
    """``count`` held-out histories (and the clips' shapes), walking clips first."""
    walks = [m for m in motions if m.label == "walk"] or list(motions)
    rng = np.random.default_rng(seed)
    d = fitted.window
    histories, nexts, shapes = [], [], []
    usable = [m for m in walks if m.n_frames >= d + 2]
    if not usable:
        raise ValueError("tree figures: no held-out clip is long enough for a window")
    for k in range(count):
        m = usable[k % len(usable)]
        t = int(rng.integers(d, m.n_frames - 1))
        p = m.params[:, fitted.free]
        histories.append(p[t - d : t + 1])
        nexts.append(m.params[t + 1])
        shapes.append(m.shape)
    return np.array(histories), np.array(nexts), shapes


def _local_keypoints(params: FloatArray, shape: body.BodyShape) -> FloatArray:
    """Keypoints relative to the pelvis in the heading frame: (right, forward, up)."""
    kp = body.forward_kinematics(params, shape)
    rel = kp - kp[..., :1, :]
    yaw = params[..., body.PARAM_INDEX["root_yaw"]][..., None]
    c, s = np.cos(-yaw), np.sin(-yaw)
    x, y = rel[..., 0], rel[..., 1]
    return np.stack([c * x - s * y, s * x + c * y, rel[..., 2]], axis=-1)


def sample_next_poses(
    fitted: tree.TreeParams,
    history: FloatArray,
    samples: int,
    beta: float,
    rng: np.random.Generator,
) -> FloatArray:
    """``samples`` next poses ``(samples, D)`` from one history, without added noise."""
    model = fitted.with_settings(beta=beta, noise_scale=0.0)
    state = ParticleState(
        np.repeat(history[None, -1], samples, axis=0),
        tree.memory(np.repeat(history[None], samples, axis=0)),
    )
    return tree.transition(model, state, rng).pose


def next_pose_spread(
    fitted: tree.TreeParams,
    histories: FloatArray,
    shapes: Sequence[body.BodyShape],
    betas: Sequence[float],
    rng: np.random.Generator,
    samples: int = 10,
) -> FloatArray:
    """Fig. 3's measure: mean spread (mm) of ``samples`` next poses, per ``beta``.

    The spread of one history is the mean distance of the sampled poses' 15
    keypoints (relative to the pelvis, in the heading frame) from their mean.
    Needs all 25 parameters free.

    Returns:
        ``(len(betas),)`` the spread averaged over the histories.
    """
    if fitted.n_free != body.N_PARAMS:
        raise ValueError("next_pose_spread: the prior must model all 25 parameters")
    out = np.zeros(len(betas))
    for i, beta in enumerate(betas):
        spread = []
        for history, shape in zip(histories, shapes, strict=True):
            kp = _local_keypoints(sample_next_poses(fitted, history, samples, beta, rng), shape)
            spread.append(np.linalg.norm(kp - kp.mean(axis=0), axis=-1).mean())
        out[i] = np.mean(spread)
    return out


def figure3(
    fitted: tree.TreeParams,
    motions: Sequence[Motion],
    path: Path,
    seed: int,
    betas: Sequence[float] = FIG3_BETAS,
) -> FloatArray:
    """Fig. 3: sampled next poses against ``beta``; returns the spread per ``beta`` (mm)."""
    plt = pyplot()

    rng = np.random.default_rng(seed)
    histories, nexts, shapes = _probe_histories(fitted, motions, 24, seed)
    spread = next_pose_spread(fitted, histories, shapes, betas, rng)
    fig, axes = plt.subplots(1, len(betas) + 1, figsize=(3.0 * (len(betas) + 1), 3.6))
    truth = _local_keypoints(nexts[0], shapes[0])
    drawn = [
        _local_keypoints(sample_next_poses(fitted, histories[0], 10, beta, rng), shapes[0])
        for beta in betas
    ]
    every = np.concatenate([k.reshape(-1, 3) for k in drawn] + [truth])
    lo, hi = every.min(axis=0) - 50, every.max(axis=0) + 50
    for ax, beta, keypoints in zip(axes, betas, drawn, strict=False):
        for kp in keypoints:
            for a, b in body.SKELETON_EDGES:
                ax.plot(kp[[a, b], 1], kp[[a, b], 2], color="tab:blue", alpha=0.45, lw=1)
        for a, b in body.SKELETON_EDGES:
            ax.plot(truth[[a, b], 1], truth[[a, b], 2], color="black", lw=1.5)
        ax.set_title(f"beta = {beta:g}")
        ax.set_xlim(lo[1], hi[1])
        ax.set_ylim(lo[2], hi[2])
        ax.set_aspect("equal")
        ax.set_xlabel("forward (mm)")
    axes[0].set_ylabel("up (mm)")
    ax = axes[-1]
    ax.plot(betas, spread, "o-")
    ax.set_xscale("log")
    ax.set_xlabel("beta")
    ax.set_ylabel("spread of 10 next poses (mm)")
    ax.set_title("spread grows with beta")
    fig.suptitle("Fig. 3: 10 sampled next poses (blue) and the true next pose (black)")
    save(fig, path)
    return spread


def figure4(
    fitted: tree.TreeParams,
    motions: Sequence[Motion],
    path: Path,
    seed: int,
    beta: float = 1.0,
    draws: int = 20000,
) -> None:
    """Fig. 4: the tree's sampled coefficients beside eq. 3's Gaussian and exact draws."""
    plt = pyplot()

    rng = np.random.default_rng(seed)
    histories, _, _ = _probe_histories(fitted, motions, 1, seed)
    probe = tree.window_coefficients(fitted, histories)[0]
    many = np.repeat(probe[None], draws, axis=0)
    by_tree = fitted.coefficients[tree.sample_windows(fitted, many, rng, beta)]
    exact = fitted.coefficients[tree.sample_exact(fitted, many[: max(1, draws // 4)], rng, beta)]
    shown = min(4, fitted.depth)
    fig, axes = plt.subplots(1, shown, figsize=(3.2 * shown, 3.2), squeeze=False)
    for level, ax in enumerate(axes[0]):
        scale = np.sqrt(beta) * fitted.sigma[level]
        lo = min(probe[level] - 4 * scale, by_tree[:, level].min())
        hi = max(probe[level] + 4 * scale, by_tree[:, level].max())
        bins = np.linspace(lo, hi, 50)
        ax.hist(fitted.coefficients[:, level], bins, density=True, color="0.85",
                label="database")  # fmt: skip
        ax.hist(by_tree[:, level], bins, density=True, histtype="step", lw=1.5,
                label="tree samples")  # fmt: skip
        ax.hist(exact[:, level], bins, density=True, histtype="step", lw=1.5, ls="--",
                label="exact eq. 3")  # fmt: skip
        grid = np.linspace(lo, hi, 200)
        gauss = np.exp(-0.5 * ((grid - probe[level]) / scale) ** 2) / (scale * np.sqrt(2 * np.pi))
        ax.plot(grid, gauss, color="black", lw=1, label="N(c_t, beta sigma^2)")
        ax.axvline(0.0, color="0.5", lw=0.5)
        ax.set_title(f"coefficient {level + 1}")
    axes[0][0].legend(fontsize=7)
    fig.suptitle(f"Fig. 4: coefficients of sampled windows, beta = {beta:g}")
    save(fig, path)


def make_figures(
    library: MotionLibrary,
    out_dir: str | Path,
    seed: int = 0,
    log: Callable[[str], None] | None = None,
) -> dict[str, Path]:
    """Fit the whole-body tree on the training split and draw Figs. 3 and 4.

    Args:
        library: The motion library (its ``"train"`` split is the database,
            probes come from its ``"test"`` split, walking clips first).
        out_dir: Folder for the PNG files (created).
        seed: Seed of every random choice.
        log: Told Fig. 3's numbers (the spread at each beta), which docs quote.

    Returns:
        ``{"fig3": path, "fig4": path}``.

    Raises:
        ValueError: If either split is empty.
    """
    train, test = library.split("train"), library.split("test")
    if not len(train) or not len(test):
        raise ValueError("tree figures: the library needs clips in both the train and test split")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    fitted = tree.fit(train.motions)
    paths = {"fig3": out / "tree_fig3_beta_spread.png", "fig4": out / "tree_fig4_coefficients.png"}
    spread = figure3(fitted, test.motions, paths["fig3"], seed)
    if log is not None:
        shown = ", ".join(f"{s:.0f}" for s in spread)
        log(f"fig3: spread of the sampled next poses {shown} mm for beta = {list(FIG3_BETAS)}")
    figure4(fitted, test.motions, paths["fig4"], seed)
    return paths


#: The feature sets :func:`explained_variance_by_features` compares.
FEATURE_SETS: tuple[str, ...] = ("pose+velocity", "pose", "velocity")


def explained_variance_by_features(
    fitted: tree.TreeParams, components: int | None = None, windows: int = 15000, seed: int = 0
) -> list[dict[str, float | int | str]]:
    """What share of the windows' variance ``b`` components hold, by feature set and scaling.

    The paper's 16 components held 89% of the variance of its database
    (section 4; the shared data's numbers are in docs/priors.md). This
    recomputes the share on a sample of the prior's windows for the features
    the prior uses (every frame's absolute parameters and every free
    parameter's velocity), the poses alone and the velocities alone, each with
    the per-feature scaling ``Gamma^-1/2`` of section 4 and without it.

    Args:
        fitted: A fitted tree prior.
        components: ``b`` (the prior's depth when None).
        windows: Windows sampled (all when fewer).
        seed: Seeds the sample.

    Returns:
        One row per (features, scaled): ``features``, ``scaled``, ``explained``
        and ``components_for_89`` (how many components hold 89%).

    Raises:
        ValueError: If ``components`` or ``windows`` < 1.
    """
    b = fitted.depth if components is None else int(components)
    if b < 1 or windows < 1:
        raise ValueError(f"components and windows: expected at least 1, got {b} and {windows}")
    rng = np.random.default_rng(seed)
    pick = np.sort(rng.choice(fitted.n_windows, min(windows, fitted.n_windows), replace=False))
    # the windows as the prior's search sees them (section 4): anchored, with velocities
    lay = tree_model._layout(fitted.free)
    feats = tree_model._features(tree_model._anchor(tree.window_histories(fitted, pick), lay), lay)
    n_abs = lay.absolute.size
    parts = {
        "pose+velocity": feats,
        "pose": feats[..., :n_abs],
        "velocity": feats[..., n_abs:],
    }
    rows: list[dict[str, float | int | str]] = []
    for name in FEATURE_SETS:
        x = parts[name].reshape(pick.size, -1)
        x = x - x.mean(axis=0)
        for scaled in (True, False):
            y = x / np.maximum(x.std(axis=0), 1e-12) if scaled else x
            power = np.linalg.svd(y, compute_uv=False) ** 2
            share = np.cumsum(power) / power.sum()
            rows.append(
                {
                    "features": name,
                    "scaled": scaled,
                    "explained": float(share[min(b, share.size) - 1]),
                    "components": b,
                    "components_for_89": int(np.searchsorted(share, 0.89) + 1),
                    "dimensions": int(share.size),
                }
            )
    return rows
