"""Walking cycles (section 3 of Ormoneit et al. 2005) against hand values and slow references."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from baselines.priors import cycles


def _sine_curve(phase: np.ndarray) -> np.ndarray:
    k = 2 * np.pi * phase
    return np.stack([np.sin(k), np.cos(2 * k) + 0.5 * np.sin(k)], axis=-1)


def test_the_basis_derivatives_are_the_derivatives_of_the_basis() -> None:
    """Derivatives 1 and 2 against central differences of the order below (1e-6)."""
    x = (np.arange(40) + 0.5) / 40  # 0.0125 or more from the knots 0.1, ..., 0.9
    h = 1e-6
    for d in (1, 2):
        below = [cycles.truncated_power_basis(x + s * h, derivative=d - 1) for s in (1, -1)]
        numeric = (below[0] - below[1]) / (2 * h)
        exact = cycles.truncated_power_basis(x, derivative=d)
        np.testing.assert_allclose(exact, numeric, rtol=1e-6, atol=1e-6)
    with pytest.raises(ValueError, match="derivative must be 0, 1 or 2"):
        cycles.truncated_power_basis(x, derivative=3)


def test_nearest_turn_moves_each_angles_median_into_minus_pi_to_pi() -> None:
    """Medians 350 deg, 170 deg and -200 deg: shifted by -1, 0 and +1 turns."""
    med = np.radians([350.0, 170.0, -200.0])
    series = med + np.array([[-0.1], [0.0], [0.1]])  # three frames, median med
    got = cycles.nearest_turn(series)
    np.testing.assert_allclose(got, series + 2 * np.pi * np.array([-1.0, 0.0, 1.0]), atol=1e-12)
    # The median is over the observed frames only.
    observed = np.ones((3, 3), dtype=bool)
    observed[:, 1] = [False, False, True]  # angle 1's only observed frame: 170 deg + 0.1 rad
    shifted = series.copy()
    shifted[:2, 1] = 100.0  # unobserved garbage
    got = cycles.nearest_turn(shifted, observed)
    assert got[2, 1] == pytest.approx(series[2, 1])


def test_candidate_periods_span_half_a_second_to_two_or_half_the_clip() -> None:
    """At 30 fps: 15 to 60 frames a quarter frame apart, capped at half the clip."""
    full = cycles.candidate_periods(30.0)
    assert full[0] == 15.0 and full[-1] == 60.0 and full.size == 181
    np.testing.assert_allclose(np.diff(full), 0.25)
    assert cycles.candidate_periods(30.0, 100)[-1] == 50.0
    assert cycles.candidate_periods(30.0, 29).size == 0  # 14.5 < 15: too short
    assert cycles.candidate_periods(4.0)[0] == 3.0  # never under 3 frames


def reference_snr(x: np.ndarray, w: np.ndarray, p: float) -> np.ndarray:
    """Eqs. 1-3 written out per angle and bin, from the module docstring."""
    n_bins = int(np.floor(p))
    out = np.zeros(x.shape[1])
    for j in range(x.shape[1]):
        t = np.flatnonzero(w[:, j])
        v = x[t, j]
        b = np.floor((t % p) / p * n_bins).astype(int)
        m = v.mean()
        groups = [v[b == k] for k in range(n_bins) if np.any(b == k)]
        signal = sum(g.size * (g.mean() - m) ** 2 for g in groups) / (len(groups) - 1)
        noise = sum(((g - g.mean()) ** 2).sum() for g in groups) / (v.size - len(groups))
        out[j] = signal / noise
    return out


def test_signal_to_noise_is_the_one_way_anova_f_statistic() -> None:
    """The vectorised ratio against the per-bin reference, fractional periods, with gaps."""
    rng = np.random.default_rng(0)
    t = np.arange(97)[:, None]
    x = np.sin(2 * np.pi * t / 11.3 + np.array([0.0, 1.0, 2.0])) + 0.3 * rng.standard_normal(
        (97, 3)
    )
    w = rng.random(x.shape) > 0.25
    periods = np.array([5.0, 7.4, 11.3, 12.75, 20.0])
    got = cycles.signal_to_noise(np.where(w, x, 1e6), w, periods)
    want = np.stack([reference_snr(x, w, p) for p in periods])
    np.testing.assert_allclose(got, want, rtol=1e-9)


def test_estimate_period_gives_nan_when_the_ratio_still_rises_at_the_longest_candidate() -> None:
    """A 70-frame clip of a 50-frame cycle at 30 fps: its period cannot show twice."""
    t = np.arange(70)[:, None]
    x = np.sin(2 * np.pi * t / 50.0)
    periods = cycles.candidate_periods(30.0, 70)
    snr = cycles.signal_to_noise(x, None, periods).sum(axis=1)
    assert int(np.argmax(snr)) == periods.size - 1  # the premise: still rising at 35 frames
    assert np.isnan(cycles.estimate_period(x, fps=30.0))
    # Candidates given explicitly are taken as they are.
    assert cycles.estimate_period(x, periods=periods) == periods[-1]
    # 100 frames of a 40-frame cycle: the maximum is inside the range.
    x = np.sin(2 * np.pi * np.arange(100)[:, None] / 40.0)
    assert cycles.estimate_period(x, fps=30.0) == 40.0


def test_estimate_period_gives_nan_for_a_clip_that_shows_no_cycle() -> None:
    """Nothing observed, or nothing moving: every ratio is 0, not a cycle of the shortest period."""
    x = np.sin(2 * np.pi * np.arange(100)[:, None] / 40.0) * np.ones((1, 3))
    assert np.isnan(cycles.estimate_period(x, np.zeros(x.shape, dtype=bool), fps=30.0))
    assert np.isnan(cycles.estimate_period(np.full((100, 3), 0.3), fps=30.0))
    assert np.isnan(cycles.estimate_period(np.full((100, 3), 0.3), periods=[20.0, 25.0]))


@pytest.fixture(scope="module")
def gappy_alignment() -> tuple[cycles.Alignment, list[np.ndarray], list[np.ndarray]]:
    rng = np.random.default_rng(3)
    periods = np.array([30.0, 26.5, 33.0])
    xs, ws = [], []
    for p, d in zip(periods, (0.0, 0.3, 0.65), strict=True):
        t = np.arange(150)
        x = _sine_curve(t / p - d)
        w = rng.random(x.shape) > 0.3
        xs.append(np.where(w, x, 50.0))  # garbage where unobserved must not matter
        ws.append(w)
    return cycles.align_offsets(xs, periods, ws), xs, ws


def test_alignment_errors_are_the_mean_squared_error_over_observed_entries(gappy_alignment) -> None:
    """``errors[-1]`` recomputed from the reference curves; noise-free data fit to 1e-5."""
    al, xs, ws = gappy_alignment
    sse = sum(
        np.sum(np.where(w, x - al.reference(al.phases(i, x.shape[0])), 0.0) ** 2)
        for i, (x, w) in enumerate(zip(xs, ws, strict=True))
    )
    n_obs = sum(int(w.sum()) for w in ws)
    assert al.errors[-1] == pytest.approx(sse / n_obs, rel=1e-9)
    # Noise-free sines: the periodic spline with 9 knots fits them to ~1e-4 (mse ~1e-8).
    assert al.errors[-1] < 1e-5


def test_alignment_stops_at_the_first_improvement_under_tol(gappy_alignment) -> None:
    """Fig. 6's loop: every improvement but the last exceeds ``tol`` relative, the last does not."""
    al, _, _ = gappy_alignment
    gains = -np.diff(al.errors) / al.errors[:-1]
    assert al.errors.size >= 3
    assert np.all(gains[:-1] > 1e-6) and gains[-1] <= 1e-6


def test_alignment_offsets_are_exact_on_noise_free_curves(gappy_alignment) -> None:
    """Shifts 0, 0.3, 0.65 cycles recovered to 1e-3 cycle (the FFT grid is 1/128)."""
    al, _, _ = gappy_alignment
    rel = al.offsets / al.periods - np.array([0.0, 0.3, 0.65])
    rel = (rel - rel[0] + 0.5) % 1.0 - 0.5
    assert np.abs(rel).max() < 1e-3


def test_the_first_reference_is_fitted_to_the_best_observed_sequence(gappy_alignment) -> None:
    """``anchor=None`` is the sequence with the most observed entries."""
    _, xs, ws = gappy_alignment
    best = int(np.argmax([w.sum() for w in ws]))
    assert best != int(np.argmin([w.sum() for w in ws]))
    default = cycles.align_offsets(xs, [30.0, 26.5, 33.0], ws)
    explicit = cycles.align_offsets(xs, [30.0, 26.5, 33.0], ws, anchor=best)
    np.testing.assert_array_equal(default.offsets, explicit.offsets)
    np.testing.assert_array_equal(default.errors, explicit.errors)


def test_cycle_shifts_recover_each_whole_cycles_phase_shift(gappy_alignment) -> None:
    """Cycles shifted by known multiples of 1/256 cycle; partial and sparse cycles left out."""
    al, _, _ = gappy_alignment
    # Cycle k spans frames 28 + 30 k .. 57 + 30 k, half a frame inside its ends;
    # cycle -1 (frames 0..27, 2.5 frames in) is partial: left out.
    p, offset = 30.0, 27.5
    one = dataclasses.replace(al, periods=np.array([p]), offsets=np.array([offset]))
    shifts = np.array([10, -6, 0, 40, 20]) / 256  # cycles 0..4; 40/256 is outside +-0.125
    t = np.arange(int(offset + 5 * p) + 10)  # and a partial cycle 5 at the end
    u = (t - offset) / p
    k = np.clip(np.floor(u).astype(int), 0, 4)
    x = one.reference(u - shifts[k])
    w = np.ones(x.shape, dtype=bool)
    start = int(np.ceil(offset + 2 * p))
    w[start : start + 10] = False  # cycle 2 a third unobserved: kept
    (got,) = cycles.cycle_shifts(one, [x], [w], max_shift=0.125)
    assert got.size == 5  # cycles 0..4
    np.testing.assert_allclose(got[[0, 1, 2, 4]], shifts[[0, 1, 2, 4]], atol=1e-12)
    assert abs(got[3]) <= 0.125 and got[3] > 0.1  # the best shift inside the window
    w[start : start + 16] = False  # cycle 2 over half unobserved: left out
    (got,) = cycles.cycle_shifts(one, [x], [w], max_shift=0.125)
    np.testing.assert_allclose(got[[0, 1, 3]], shifts[[0, 1, 4]], atol=1e-12)
    assert got.size == 4


def test_to_frames_interpolates_between_samples_and_into_the_next_cycle() -> None:
    """Period 8, 4 samples: frame t of cycle k sits at sample (t mod 8) / 2 (hand values)."""
    seg = cycles.Segmentation(
        values=np.array([[[0.0, 1.0, 2.0, 3.0]], [[10.0, 11.0, 12.0, 13.0]]]),
        observed=np.ones((2, 1, 4), dtype=bool),
        sequence=np.array([0, 0]),
        cycle=np.array([0, 1]),
        periods=np.array([8.0]),
        offsets=np.array([0.0]),
        n_frames=np.array([20]),
    )
    back = seg.to_frames(seg.values, 0)[:, 0]
    np.testing.assert_allclose(back[[0, 1, 2, 3]], [0.0, 0.5, 1.0, 1.5])
    assert back[7] == pytest.approx(6.5)  # between sample 3 (3) and cycle 1's sample 0 (10)
    assert back[9] == pytest.approx(10.5)
    assert back[15] == pytest.approx(11.5)  # cycle 2 dropped: back to cycle 1's own first (10)
    assert np.isnan(back[16:]).all()


def test_cycle_knots_are_at_most_a_tenth_of_a_cycle_and_the_frame_bound_apart() -> None:
    """Clamped cubic knots over [-margin, 1 + margin], gaps <= min(0.1, frames_per_knot / p)."""
    for period, margin, per_knot in ((30.0, 0.1, 2.0), (10.0, 0.2, 2.0), (100.0, 0.1, 50.0)):
        knots = cycles.cycle_knots(period, margin, per_knot)
        assert np.all(knots[:4] == -margin) and np.all(knots[-4:] == 1 + margin)
        gaps = np.diff(knots[3:-3])
        assert np.all(gaps > 0) and gaps.max() <= min(0.1, per_knot / period) + 1e-12


def test_segment_marks_missing_exactly_the_samples_outside_or_beside_unobserved_frames() -> None:
    """Period 20 with 40 samples: sample s of cycle k at frame 20 k + s / 2."""
    t = np.arange(60)[:, None]
    x = np.sin(2 * np.pi * t / 20.0) * np.array([1.0, 0.5])
    w = np.ones(x.shape, dtype=bool)
    w[25] = False
    seg = cycles.segment([x], [20.0], [0.0], [w], n_samples=40)
    assert seg.cycle.tolist() == [0, 1, 2]
    assert seg.observed[0].all()  # sample 0 at frame 0 is inside the clip
    missing = np.flatnonzero(~seg.observed[1, 0])
    assert missing.tolist() == [9, 10, 11]  # frames 24.5, 25, 25.5
    assert seg.observed[1, :, [8, 12]].all()
    np.testing.assert_array_equal(seg.observed[1, 0], seg.observed[1, 1])
    # The last cycle: samples past frame 59 are missing.
    np.testing.assert_array_equal(seg.observed[2, 0], np.arange(40) / 2 + 40 <= 59)


def test_segment_drops_cycles_under_the_coverage() -> None:
    """Cycle 1 with 6 of its 20 samples observed (0.3): kept at 0.2 and 0.3, dropped at 0.35."""
    t = np.arange(60)[:, None]
    x = np.sin(2 * np.pi * t / 20.0)
    w = np.ones(x.shape, dtype=bool)
    w[26:40] = False
    for coverage, kept in ((0.2, True), (0.3, True), (0.35, False)):
        seg = cycles.segment([x], [20.0], [0.0], [w], n_samples=20, min_coverage=coverage)
        assert (1 in seg.cycle) is kept


def test_a_cycles_fit_uses_its_frames_and_a_margin_either_side() -> None:
    """Changing a frame inside the margin after a cycle changes it; one beyond does not."""
    t = np.arange(80)[:, None]
    x = np.sin(2 * np.pi * t / 20.0)

    def cycle_1(frame: int) -> np.ndarray:
        bumped = x.copy()
        bumped[frame] += 1.0
        seg = cycles.segment([bumped], [20.0], [0.0], n_samples=20, margin=0.2)
        return seg.values[seg.cycle == 1][0, 0]

    base = cycles.segment([x], [20.0], [0.0], n_samples=20, margin=0.2)
    plain = base.values[base.cycle == 1][0, 0]
    for frame in (17, 42):  # 0.15 cycle before, 0.1 cycle after cycle 1 (frames 20-39)
        assert np.abs(cycle_1(frame) - plain).max() > 1e-3
    for frame in (14, 46):  # 0.3 cycle either side: outside the margin
        np.testing.assert_allclose(cycle_1(frame), plain, atol=1e-9)


def test_a_shift_that_does_not_lower_the_error_is_not_taken() -> None:
    """A clip that is exactly a periodic spline at offset 0: no trial shift is better, none kept."""
    coef = np.random.default_rng(5).standard_normal((2, 10))
    x = cycles.periodic_spline_basis(np.arange(120) / 29.0) @ coef.T
    al = cycles.align_offsets([x], [29.0])
    assert min(al.offsets[0], 29.0 - al.offsets[0]) < 1e-6  # frames
    assert np.all(np.diff(al.errors) <= 0.0)
    assert al.errors[-1] < 1e-10  # the ridge's bias only


def test_a_whole_period_counts_every_cycle_one_frame_short_of_its_end(gappy_alignment) -> None:
    """Period 30, offset 28: every cycle's last frame is exactly one frame before its end,
    so each of the five whole cycles counts, however its phases round."""
    al, _, _ = gappy_alignment
    one = dataclasses.replace(al, periods=np.array([30.0]), offsets=np.array([28.0]))
    t = np.arange(28 + 5 * 30)  # a partial cycle -1, then cycles 0..4 exactly
    x = one.reference((t - 28.0) / 30.0)
    (got,) = cycles.cycle_shifts(one, [x], [np.ones(x.shape, dtype=bool)], max_shift=0.125)
    assert got.size == 5
    np.testing.assert_allclose(got, 0.0, atol=1e-12)
