"""The SLDS's learned-emission M-step, ``stabilise`` and the covariance table against oracles."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from test_slds import _rot, _spd, random_model  # the same small random models
from test_slds_oracles import smoothed_on_a_random_path

from baselines.priors import slds
from baselines.priors.slds_inference import (
    COV_RTOL,
    CovarianceTable,
    Sequences,
    SLDSParams,
    SmootherResult,
    filter_path,
    measurement_terms,
    rts_smoother,
    stabilise,
)
from baselines.priors.slds_learning import Regulariser, _accumulate, _Stats, m_step


def reference_emission(
    params: SLDSParams, reg: Regulariser, seqs: Sequences, sm: SmootherResult
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``[C|d]`` and ``R`` of the MAP M-step, frame by frame (learned emission).

    ``[C|d]`` solves the ridge-regularised normal equations of ``y`` on
    ``u = [x; 1]`` over the measured frames; ``R_ii`` is the expected squared
    residual ``E[(y - C x - d)_i^2] = (y - C m - d)_i^2 + (C P C')_ii`` summed,
    plus the ridge's and the prior's terms, over ``n_obs + kappa_r`` frames.
    """
    dx, dy = params.latent_dim, params.obs_dim
    e_uu, e_yu, frames = np.zeros((dx + 1, dx + 1)), np.zeros((dy, dx + 1)), []
    for k in range(seqs.n):
        for t in range(seqs.lengths[k]):
            if not seqs.observed[k, t]:
                continue
            m, p, y = sm.mean[k, t], sm.cov[k, t], seqs.y[k, t]
            u = np.append(m, 1.0)
            e_uu += np.outer(u, u)
            e_uu[:dx, :dx] += p
            e_yu += np.outer(y, u)
            frames.append((m, p, y))
    cd = e_yu @ np.linalg.inv(e_uu + np.diag(reg.ridge_c))
    c, d = cd[:, :dx], cd[:, dx]
    resid = sum((y - c @ m - d) ** 2 + np.diag(c @ p @ c.T) for m, p, y in frames)
    ridge_term = np.diag(cd @ np.diag(reg.ridge_c) @ cd.T)
    r = (resid + ridge_term + reg.psi_r) / (len(frames) + reg.kappa_r)
    return c, d, np.diag(r)


def test_the_learned_emissions_m_step_is_the_map_estimate_frame_by_frame() -> None:
    """``C, d, R`` against the oracle, with the statistics summed over two batches."""
    params, seqs, path, sm = smoothed_on_a_random_path(21, "learned")
    dx, dy = params.latent_dim, params.obs_dim
    rng = np.random.default_rng(23)
    reg = Regulariser(
        psi_q=np.full(dx, 0.1), kappa_q=2.0, ridge=np.ones(dx + 1),
        psi_r=rng.uniform(0.1, 0.2, dy), kappa_r=3.0, ridge_c=rng.uniform(0.5, 2.0, dx + 1),
        m0=np.zeros(dx), eps0=0.7, psi0=np.full(dx, 0.1), kappa0=1.5,
    )  # fmt: skip
    stats = _Stats.zeros(params.n_states, dx, dy)
    for part in ([0, 1, 2], [3, 4]):  # an E-step sums its batches' statistics
        sub = seqs.take(part)
        smp = rts_smoother(params, path[part], filter_path(params, sub, path[part]), sub.lengths)
        _accumulate(stats, params, sub, measurement_terms(params, sub), path[part], smp)
    got = m_step(params, stats, reg)
    c, d, r = reference_emission(params, reg, seqs, sm)
    np.testing.assert_allclose(got.C, c, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(got.d, d, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(got.R, r, rtol=1e-9, atol=1e-12)


def _clipped(lam: np.ndarray, radius: float) -> np.ndarray:
    return lam * np.minimum(1.0, radius / np.abs(lam))


def test_stabilise_moves_only_the_eigenvalues_outside_the_radius() -> None:
    """Order 1 and 2: the spectrum clipped to the radius; order 1 keeps the eigenvectors."""
    rng = np.random.default_rng(24)
    for order, dy in ((1, 3), (2, 2)):
        params = random_model(rng, "identity", order=order, dy=dy)
        a = params.A.copy()
        a[0, :dy] *= 4.0  # unstable, with eigenvalues both sides of the radius below
        params = params.replace(A=a)
        lam = np.linalg.eigvals(params.A[0])
        radius = float(np.sort(np.abs(lam))[-2]) * 0.999  # at least two eigenvalues outside
        assert np.any(np.abs(lam) < radius)
        got = stabilise(params, radius)
        new = np.linalg.eigvals(got.A[0])
        want = _clipped(lam, radius)
        np.testing.assert_allclose(np.sort_complex(new), np.sort_complex(want), atol=1e-9)
        if order == 1:  # the same eigenvectors (order 2 rescales their upper block)
            np.testing.assert_allclose(got.A[0] @ params.A[0], params.A[0] @ got.A[0], atol=1e-9)
    # A learned emission (order 1, dx < dy): a rotation growing by 1.2 a frame.
    params = random_model(rng, "learned", dx=2, dy=3)
    params = params.replace(A=np.stack([1.2 * _rot(0.3), 0.5 * _rot(0.1)]))
    got = stabilise(params, 0.9)
    np.testing.assert_allclose(got.A[0], 0.9 * _rot(0.3), atol=1e-12)
    np.testing.assert_array_equal(got.A[1], params.A[1])


def test_covariances_a_power_of_two_apart_get_ids_of_their_own() -> None:
    """``P``, ``2 P`` and ``4 P`` round to the same mantissas: the exponent tells them apart."""
    rng = np.random.default_rng(25)
    params = random_model(rng, "identity", order=1, n_states=2, dy=3)
    table = CovarianceTable(params, params.R)
    p = _spd(rng, 3, 1.0)
    covs = np.stack([p, 2 * p, 4 * p, 0.5 * p])
    ids = table.insert(covs)
    assert len(set(ids.tolist())) == 4
    scale = np.abs(np.diagonal(covs, axis1=1, axis2=2)).max(axis=1)
    assert np.all(np.abs(table.cov[ids] - covs).max(axis=(1, 2)) <= COV_RTOL * scale)


def test_a_table_that_grows_keeps_what_it_held() -> None:
    """Past its first capacity (65,536 ids) every id still holds its matrix and is found again."""
    rng = np.random.default_rng(26)
    params = random_model(rng, "learned", n_states=2, dx=2, dy=3)
    table = CovarianceTable(params, params.R)
    n = 40_000
    # 40,000 matrices 1e-5 relative apart: far more than rtol, all distinct.
    first = (1.0 + 1e-5 * np.arange(n))[:, None, None] * np.array([[1.0, 0.5], [0.5, 1.0]])
    ids = table.insert(first)
    assert len(set(ids.tolist())) == n
    table.predicted(ids[:5])  # derived ids too
    pred = table.pred[ids[:5]].copy()
    second = first + 1.0  # another 40,000: the table grows
    table.insert(second)
    assert table.n >= 2 * n
    np.testing.assert_array_equal(table.cov[ids], first)
    np.testing.assert_array_equal(table.insert(first), ids)
    np.testing.assert_array_equal(table.predicted(ids[:5]), pred)


def test_covariances_farther_apart_than_the_tolerance_never_share_an_id() -> None:
    """One entry moved by 1.5 rtol of the largest variance: past a whole grid spacing, a new id."""
    rng = np.random.default_rng(27)
    params = random_model(rng, "identity", order=2, n_states=3, dy=3)
    table = CovarianceTable(params, params.R)
    base = np.stack([_spd(rng, 6, 1.0) for _ in range(20)])
    scale = np.abs(np.diagonal(base, axis1=1, axis2=2)).max(axis=1)
    moved = base.copy()
    moved[:, 0, 1] += 1.5 * COV_RTOL * scale  # off the diagonal: the scale stays
    moved[:, 1, 0] = moved[:, 0, 1]
    ids = table.insert(base)
    got = table.insert(moved)
    assert not np.any(got == ids)
    assert np.all(np.abs(table.cov[got] - moved).max(axis=(1, 2)) <= COV_RTOL * scale)


def test_a_colliding_covariance_never_takes_the_indexed_ones_place() -> None:
    """Every hash equal: the first matrix stays found; a different one gets a new id each time."""
    rng = np.random.default_rng(28)
    params = random_model(rng, "identity", order=1, n_states=2, dy=3)
    table = CovarianceTable(params, params.R)
    table._mult[:] = 0  # every key hashes to 0
    a, b = _spd(rng, 3, 1.0), _spd(rng, 3, 1.0)
    (first,) = table.insert(a[None])
    (other,) = table.insert(b[None])
    assert other != first
    assert table.insert(a[None])[0] == first
    again = table.insert(b[None])[0]
    assert again not in (first, other)
    np.testing.assert_array_equal(table.cov[[first, other, again]], [a, b, b])


def test_a_reset_table_starts_empty_even_for_the_same_model() -> None:
    """After ``reset`` the same matrices get the fresh table's ids, none left from before."""
    rng = np.random.default_rng(29)
    params = random_model(rng, "identity", order=1, n_states=2, dy=3)
    base = np.stack([_spd(rng, 3, 1.0) for _ in range(5)])
    table = CovarianceTable(params, params.R)
    table.insert(np.stack([_spd(rng, 3, 1.0) for _ in range(7)]))
    table.insert(base)  # ids 7..11
    table.reset(params, params.R)
    ids = table.insert(base)
    np.testing.assert_array_equal(ids, CovarianceTable(params, params.R).insert(base))
    assert table.n == 5 and np.all(ids < table.n)


def _flip_first_pair(q: np.ndarray) -> np.ndarray:
    out = q.copy()
    out[..., 0, 1] += 1.0  # one entry off its transpose's
    return out


@pytest.mark.parametrize(
    ("member", "change", "says"),
    [
        ("pi0", lambda a: -a, r"pi0 must be probabilities in \[0, 1\] summing to 1, got"),
        ("Pi", lambda a: 3 * a, r"Pi must be probabilities .* summing to 1 in each row"),
        ("Q", lambda a: -a, "Q must be covariance matrices with variances >= 0"),
        ("Q0", _flip_first_pair, "Q0 must be symmetric covariance matrices"),
        ("R", lambda a: -a, "R must be covariance matrices with variances >= 0"),
        ("free", lambda a: a + 30, r"free must be distinct integer indices in \[0, 25\)"),
        ("free", lambda a: a.astype(float), "free must be distinct integer indices"),
        ("free", lambda a: np.zeros_like(a), "free must be distinct integer indices"),
        ("fps", lambda a: 0.0 * a, "fps must be > 0"),
        ("switch_prob", lambda a: a + 1.0, r"switch_prob must be in \[0, 1\)"),
    ],
)
def test_load_refuses_values_initial_and_transition_cannot_use(
    tmp_path: Path, member, change, says
) -> None:
    """A negative pi0 or Q loaded (np.log warned at the first initial), a free index out of
    range or a float failed with an IndexError in initial or transition."""
    model = random_model(np.random.default_rng(4), emission="identity", order=2, n_states=3)
    good, bad = tmp_path / "good.npz", tmp_path / "bad.npz"
    slds.save(model, good)
    slds.load(good)  # the model itself is fine
    with np.load(good) as data:
        arrays = {k: data[k] for k in data.files}
    arrays[member] = np.asarray(change(arrays[member]))
    np.savez(bad, **arrays)
    with pytest.raises(ValueError, match=rf"bad\.npz: SLDSParams: {says}"):
        slds.load(bad)
