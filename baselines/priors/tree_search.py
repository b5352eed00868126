"""The tree prior's search: eq. 7's descent to a leaf, eq. 3's choice in it, the exact scan.

Sidenbladh, Black & Sigal, ECCV 2002, section 4 (see :mod:`baselines.priors.tree`
for the equations). The loops are compiled in :mod:`baselines.priors._tree_compiled`,
which holds eq. 3 and eq. 7 once each; this module checks arguments and
combines them.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from baselines.priors import _tree_compiled as compiled
from baselines.priors._checks import check_generator
from baselines.priors.tree_model import LEAF_RULES, FloatArray, IntArray, TreeParams


def _as_probes(coefficients: ArrayLike) -> FloatArray:
    """``(N, b)`` C-contiguous double-precision probes."""
    return np.ascontiguousarray(np.atleast_2d(np.asarray(coefficients, dtype=np.float64)))


def _database(fitted: TreeParams) -> FloatArray:
    """The windows' coefficients as the kernels read them (C order, double precision)."""
    return np.ascontiguousarray(fitted.coefficients, dtype=np.float64)


def eq3_log_weights(
    fitted: TreeParams, windows: IntArray, probes: ArrayLike, beta: float
) -> FloatArray:
    """Eq. 3's exponent ``-|c_i - c_t|^2_sigma / (2 beta)`` of each window against its probe.

    Args:
        fitted: The prior.
        windows: ``(K,)`` windows (tree order).
        probes: ``(K, b)`` a probe per window, or ``(b,)`` one for all.
        beta: The temperature.
    """
    w = np.ascontiguousarray(windows, dtype=np.intp).reshape(-1)
    c = np.asarray(probes, dtype=np.float64)
    c = np.broadcast_to(c, (w.size, fitted.depth)) if c.ndim == 1 else _as_probes(c)
    return compiled.eq3_log_weights(_database(fitted), w, c, fitted.sigma, float(beta))


def descend(
    fitted: TreeParams,
    coefficients: ArrayLike,
    rng: np.random.Generator,
    beta: float | None = None,
    want_log_prob: bool = False,
) -> tuple[IntArray, IntArray, FloatArray]:
    """Eq. 7's probabilistic descent of N probes to their leaves.

    Args:
        fitted: The prior.
        coefficients: ``(N, b)`` probe coefficients ``c_t``.
        rng: Random generator.
        beta: Temperature (``fitted.beta`` when None).
        want_log_prob: Also the log probability of reaching each leaf.

    Returns:
        ``[lo, hi)`` each probe's leaf (its windows in tree order) and the log
        probability of reaching it (zeros unless asked).
    """
    check_generator(rng, "tree.descend")  # the compiled descent draws from it
    t = fitted.beta if beta is None else float(beta)
    return compiled.descend(
        _as_probes(coefficients),
        fitted.sigma,
        t,
        fitted.node_flags,
        fitted.offsets,
        rng,
        want_log_prob,
    )


def sample_windows(
    fitted: TreeParams,
    coefficients: ArrayLike,
    rng: np.random.Generator,
    beta: float | None = None,
    leaf: str | None = None,
    proposals: int | None = None,
) -> IntArray:
    """The tree sampler: one database window per probe (eq. 7 descent, then the leaf).

    With ``proposals = K > 1`` each probe descends ``K`` times and one of the
    ``K`` windows is kept with probability proportional to its importance
    weight ``p_eq3(i) / q_tree(i)`` (sampling-importance-resampling): the
    draws approach eq. 3 exactly as ``K`` grows, at ``K`` times the cost.

    Args:
        fitted: The prior.
        coefficients: ``(N, b)`` probe coefficients ``c_t``.
        rng: Random generator.
        beta: Temperature (``fitted.beta`` when None).
        leaf: Leaf rule (``fitted.leaf`` when None).
        proposals: Descents per probe (``fitted.proposals`` when None; 1 is
            the paper's search).

    Returns:
        ``(N,)`` window indices (tree order).

    Raises:
        ValueError: If ``leaf`` is not a rule, ``proposals < 1`` or ``rng`` is not
            a ``numpy.random.Generator``.
    """
    check_generator(rng, "tree.sample_windows")
    c = _as_probes(coefficients)
    t = fitted.beta if beta is None else float(beta)
    rule = fitted.leaf if leaf is None else leaf
    k = fitted.proposals if proposals is None else int(proposals)
    if rule not in LEAF_RULES:
        raise ValueError(f"tree: leaf must be one of {LEAF_RULES}, got {rule!r}")
    if k < 1:
        raise ValueError(f"tree: proposals must be >= 1, got {k}")
    if k > 1:
        c = np.repeat(c, k, axis=0)
    lo, hi, log_prob = descend(fitted, c, rng, t, want_log_prob=k > 1)
    if rule == "uniform":
        chosen = lo + (rng.random(lo.size) * (hi - lo)).astype(np.intp)
    else:
        chosen, log_mass = compiled.choose_weighted(
            _database(fitted), c, lo, hi, fitted.sigma, t, rng, k > 1
        )
    if k == 1:
        return chosen
    # Importance weights p_eq3(i) / q_tree(i) up to a constant: the leaf's eq. 3
    # mass over its probability (weighted leaf), or k(c_i) * size / P(leaf).
    if rule == "uniform":
        log_mass = eq3_log_weights(fitted, chosen, c, t) + np.log(hi - lo)
    log_iw = (log_mass - log_prob).reshape(-1, k)
    log_iw -= log_iw.max(axis=1, keepdims=True)
    cum = np.cumsum(np.exp(log_iw), axis=1)
    pick = (cum < rng.random(cum.shape[0])[:, None] * cum[:, -1:]).sum(axis=1)
    return chosen.reshape(-1, k)[np.arange(cum.shape[0]), np.minimum(pick, k - 1)]


def exact_probabilities(
    fitted: TreeParams, coefficient: ArrayLike, beta: float | None = None
) -> FloatArray:
    """Eq. 3 over all ``n`` windows for one probe ``c_t`` of shape ``(b,)``."""
    t = fitted.beta if beta is None else float(beta)
    logw = eq3_log_weights(fitted, np.arange(fitted.n_windows), coefficient, t)
    w = np.exp(logw - logw.max())
    return w / w.sum()


def sample_exact(
    fitted: TreeParams,
    coefficients: ArrayLike,
    rng: np.random.Generator,
    beta: float | None = None,
) -> IntArray:
    """Exact scan: one window per probe drawn from eq. 3 over all ``n`` windows.

    ``O(n b)`` per probe; the reference the tree is tested and timed against.

    Args:
        fitted: The prior.
        coefficients: ``(N, b)`` probe coefficients.
        rng: Random generator.
        beta: Temperature (``fitted.beta`` when None).

    Returns:
        ``(N,)`` window indices (tree order).
    """
    check_generator(rng, "tree.sample_exact")
    t = fitted.beta if beta is None else float(beta)
    return compiled.sample_exact(_database(fitted), _as_probes(coefficients), fitted.sigma, t, rng)
