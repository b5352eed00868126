"""Functional PCA speed: Fig. 8's iteration against a plain SVD and a plain FPCA.

Run: ``python benchmarks/bench_fpca.py``. The data are 100 walking cycles x 19
joint angles x 120 samples (the built-in synthetic walks cut into cycles by
:mod:`baselines.priors.cycles`), with about a tenth of the entries removed
in spans of 10-50 samples. Measured in
the same process (these machines are noisy: compare ratios):

* ``plain SVD``: ``numpy.linalg.svd`` of the centred ``(100, 19 * 39)`` Fourier
  coefficient matrix, the core of one iteration (the reference of the target
  "each iteration within 2x of a plain SVD").
* ``FPCA iteration``: one iteration of :func:`baselines.priors.fpca.fpca`
  (batched rFFT of the segments, rank-q reconstruction, inverse FFT,
  imputation), the mean over 50 iterations with the tolerance off.
* ``FPCA fit``: the whole fit with imputation to the paper's tolerance (1e-6).
* ``reference FPCA``: a plain basis-expansion FPCA *without* missing data on
  the same cycles before the gaps were cut, the way a functional-data library does it (e.g.
  scikit-fda's ``FPCA`` on a basis representation): least-squares coefficients
  of every curve on a 39-function Fourier basis, weighting by the Cholesky
  factor of the basis Gram matrix, mean, SVD, components back to curves.
  scikit-fda itself is not installed here; its FPCA was quoted at about 160 ms
  on this size.

Both ``humotion_gym`` runs and the references use one BLAS thread (as ``fpca``
does itself when ``threadpoolctl`` is installed).
"""

from __future__ import annotations

import numpy as np
from _timing import best_of, no_arguments

from baselines.priors import cycles, fpca
from humotion_gym.mocap.synthetic import synthetic_motions
from humotion_gym.threads import single_threaded_blas

N_CYCLES, N_SAMPLES, N_HARMONICS, N_COMPONENTS = 100, 120, 20, 5


def walking_cycles(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(values, observed, complete)``: 100 whole cycles with gaps cut in, and as they were."""
    walks = [m for m in synthetic_motions(seed=0, n_subjects=12, seconds=10.0) if m.label == "walk"]
    xs = [m.params[:, cycles.JOINT_ANGLES] for m in walks]
    periods = np.array([cycles.estimate_period(x, None, 30.0) for x in xs])
    alignment = cycles.align_offsets(xs, periods)
    seg = cycles.segment(xs, periods, alignment.offsets, n_samples=N_SAMPLES)
    whole = np.flatnonzero(seg.observed.all(axis=(1, 2)))
    if whole.size < N_CYCLES:
        raise RuntimeError(f"only {whole.size} complete synthetic cycles, need {N_CYCLES}")
    values = seg.values[whole[:N_CYCLES]]
    observed = np.ones(values.shape, dtype=bool)
    complete = values.copy()
    # Remove spans of 10-50 samples in random angles until ~10 % is missing.
    while observed.mean() > 0.9:
        c, j = rng.integers(N_CYCLES), rng.integers(values.shape[1])
        length = int(rng.integers(10, 51))
        start = int(rng.integers(0, N_SAMPLES - length))
        observed[c, j, start : start + length] = False
    return values, observed, complete


def reference_fpca(curves: np.ndarray, n_components: int) -> tuple[np.ndarray, np.ndarray]:
    """Plain basis-expansion FPCA of complete curves ``(C, J, S)``: mean and components."""
    c, j, s = curves.shape
    t = np.arange(s) / s
    k = np.arange(1, N_HARMONICS)
    basis = np.concatenate(
        [np.ones((s, 1)), np.cos(2 * np.pi * np.outer(t, k)), np.sin(2 * np.pi * np.outer(t, k))],
        axis=1,
    )  # (S, 2H - 1)
    coef = np.linalg.lstsq(basis, curves.reshape(-1, s).T, rcond=None)[0]  # (B, C * J)
    coef = coef.T.reshape(c, j, -1)
    gram = basis.T @ basis / s  # inner products of the basis functions (quadrature)
    chol = np.linalg.cholesky(gram)
    weighted = (coef @ chol).reshape(c, -1)
    mean = weighted.mean(axis=0)
    _, sv, vt = np.linalg.svd(weighted - mean, full_matrices=False)
    comps = np.linalg.solve(
        chol.T, vt[:n_components].reshape(n_components, j, -1).transpose(0, 2, 1)
    )
    mean_curves = (np.linalg.solve(chol.T, mean.reshape(j, -1).T).T) @ basis.T
    return mean_curves, np.einsum("qbj,sb->qjs", comps, basis)


def main() -> None:
    no_arguments(__doc__)
    rng = np.random.default_rng(0)
    values, observed, complete = walking_cycles(rng)
    print(
        f"data: {values.shape[0]} cycles x {values.shape[1]} angles x {values.shape[2]} samples, "
        f"{100 * (1 - observed.mean()):.1f}% missing (the reference FPCA gets them complete); "
        f"q = {N_COMPONENTS}, {N_HARMONICS} harmonics"
    )
    with single_threaded_blas():
        z = fpca.to_coefficients(np.where(observed, values, 0.0), N_HARMONICS)
        z = z.reshape(values.shape[0], -1)
        zc = z - z.mean(axis=0)
        t_svd = best_of(lambda: np.linalg.svd(zc, full_matrices=False), 20)
        iters = 50

        def fixed_iterations() -> None:
            fpca.fpca(values, observed, N_COMPONENTS, N_HARMONICS, tol=-1.0, max_iter=iters)

        t_iter = best_of(fixed_iterations, 1, repeats=5) / iters
        fit = fpca.fpca(values, observed, N_COMPONENTS, N_HARMONICS)
        t_fit = best_of(lambda: fpca.fpca(values, observed, N_COMPONENTS, N_HARMONICS), 1, 5)
        t_ref = best_of(lambda: reference_fpca(complete, N_COMPONENTS), 5)
    monotone = bool(np.all(np.diff(fit.errors) <= 1e-12 * fit.errors[:-1]))
    rows = [
        ("plain SVD of the Fourier coefficients", t_svd, ""),
        ("FPCA iteration (Fig. 8)", t_iter, f"{t_iter / t_svd:.2f} x plain SVD (target <= 2)"),
        (
            "FPCA fit with imputation, tol 1e-6",
            t_fit,
            f"{fit.n_iter} iterations, error non-increasing: {monotone}",
        ),
        ("reference FPCA without missing data", t_ref, "plain basis expansion + SVD"),
        ("scikit-fda FPCA (quoted, not installed)", 0.160, "about 160 ms on this size"),
    ]
    print(f"{'':48s} {'ms':>9s}")
    for name, seconds, note in rows:
        print(f"{name:48s} {1e3 * seconds:9.2f}   {note}")
    print(
        f"fit with imputation / reference FPCA without missing data: {t_fit / t_ref:.2f}; "
        f"/ scikit-fda's quoted 160 ms: {t_fit / 0.160:.2f}"
    )


if __name__ == "__main__":
    main()
