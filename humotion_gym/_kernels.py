"""Compiled kernels (numba, the optional ``fast`` extra): the numpy paths' numbers, sooner.

Each kernel here does what a numpy path of the package does, in the same
floating-point operations in the same order, so the two give the same results
bit for bit (``tests/test_kernels.py`` checks it); the numpy path stays the
readable reference and runs wherever numba is not installed. Nothing else
changes: the leaderboard's tables are the same numbers with or without it.

``HUMOTION_NUMBA=0`` in the environment turns the kernels off (the numpy paths
run); :func:`enabled` says whether they are on. Where numba fails (a release
that does not support the installed numpy, a broken cache) the kernels turn
themselves off with a ``RuntimeWarning`` and the numpy paths run.

The kernels, in the order the likelihood runs them:

- :func:`pose_rows`: the poses' bounds check and the kinematics' rows of
  their parameters, in one pass;
- :func:`kinematics`: the batched forward kinematics after the sines and
  cosines (those stay numpy's: its float32 ``sin`` and ``cos`` are its own
  SIMD code, which libm's would not match);
- :func:`cone_basis`: the camera projection of the keypoints, each cone's
  image axis, normal and outline offsets, and the outline's orientation bin;
- :func:`point_costs`: the sample points placed, looked up and summed;
- :func:`coverage_sums`, :func:`residual_sums`: the whole-body tasks' coverage
  term and the arm's residual-edge term, each pose's float32 costs summed in
  double precision in numpy's pairwise order.

And the frame's features, once a frame: :func:`border_median` (the border's
median colour, from counts of its bytes), :func:`canny_gradients` (the
gradients OpenCV's Canny picks from a colour frame, which ``cv2.Canny(dx,
dy)`` then finishes), :func:`orientation_maps`, :func:`distance_maps`
(OpenCV's 5x5 chamfer distance transform, exact as far as the costs read it),
:func:`colour_distances`, :func:`foreground_map` and :func:`cost_table`. The
two that copy OpenCV (the gradients and the distances) are checked against
the installed OpenCV once on first use (``observation._kernel_canny_as_opencv``,
``_kernel_distances_as_opencv``); where it differs OpenCV runs, with a warning.

The environments' :func:`generator`: ``np.random.default_rng`` of a seed,
numpy's SeedSequence hash in compiled code (the same generator state).

And one the priors run: :func:`standard_normal`, their noise, numpy's draws
from numpy's generator (numba's port of its algorithm, same tables, same
bit generator); and one the filter runs: :func:`angle_offsets`, its circular
mean's wrapped offsets.

The renderer's: :func:`figure_polygons` and :func:`draw_figure` (the cone
figure's polygons, and OpenCV's fill of them), :func:`add_noise` (the sensor
noise, OpenCV's saturating add and subtract in one pass), :func:`draw_frames`
(the vector environment's frames, several episodes' in one call), :func:`halve_frames`
(the learners' half-size frames, OpenCV's area shrink), :func:`clutter_plan` (every
random draw of an episode's background clutter, numba's ports of numpy's
draws) and :func:`paint_texture` (its stripes and checks); the tree prior's
:func:`paced_path`, :func:`tree_descend`, :func:`leaf_log_weights`,
:func:`leaf_draws`, :func:`leaf_choice` and :func:`tree_replay` (the descent,
the choice and the replay draw from the generator as numpy would, in numpy's
order), and at an episode's start :func:`last_pose_distances` and
:func:`initial_histories` (section 6's search of the windows' last poses, and
the chosen windows placed at the pose).

Why the results match: every step the numpy paths take elementwise is one
IEEE float32 operation (add, multiply, divide, square root, comparison), and
the kernels make the same operations in the same order (numba, without
``fastmath``, neither fuses ``a * b + c`` nor reorders sums). Two steps are
matrix products, which numpy hands to BLAS ``sgemm``: the camera's rotation
of the keypoints and the sample points' placement. OpenBLAS's ``sgemm``
kernels on x86-64 accumulate each output as a chain of fused multiply-adds
over the inner dimension, in order, from zero; the kernels do exactly that
with LLVM's ``fma`` intrinsic (ordinary ``a * b + c`` would round twice). A
product with one column goes through ``sgemv`` instead, which sums
differently, so one column is left to numpy. Everything after the points'
product (clipping, truncation to a pixel, the table lookup, the integer sum)
is exact.
"""

from __future__ import annotations

import functools
import importlib
import importlib.util
import math
import os
import warnings
from collections.abc import Sequence
from types import ModuleType
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "add_noise",
    "angle_offsets",
    "border_median",
    "canny_gradients",
    "clutter_plan",
    "cone_basis",
    "colour_distances",
    "cost_table",
    "coverage_sums",
    "distance_maps",
    "draw_figure",
    "draw_frames",
    "env_keypoints",
    "env_scores",
    "figure_polygons",
    "foreground_map",
    "generator",
    "halve_frames",
    "paced_path",
    "enabled",
    "kinematics",
    "leaf_choice",
    "leaf_draws",
    "leaf_log_weights",
    "paint_texture",
    "point_costs",
    "pose_rows",
    "region_sums",
    "residual_sums",
    "spaced_rows",
    "standard_normal",
    "tree_descend",
    "tree_replay",
]

#: The most values a kernel sums in numpy's pairwise order (numpy's block of
#: eight running sums; more it splits in two recursively, which numba cannot
#: cache): terms over more points are left to numpy.
PAIRWISE_BLOCK = 128

#: The fewest draws :func:`standard_normal` hands to numba: calling a kernel
#: with a generator costs about 5 us (numba unwraps it), numpy's draws 8 ns
#: each on this project's machines, numba's 2.
NORMAL_MIN_SIZE = 2048

#: Whether the kernels run: numba is installed and ``HUMOTION_NUMBA`` is not 0.
ENABLED: bool = (
    importlib.util.find_spec("numba") is not None and os.environ.get("HUMOTION_NUMBA", "1") != "0"
)


def enabled() -> bool:
    """True when the compiled kernels run (numba installed, not turned off)."""
    return ENABLED


def spaced_rows(lead: tuple[int, ...], n: int, dtype: type = np.float32) -> NDArray:
    """An empty ``lead + (n,)`` array whose rows lie an odd number of cache lines apart.

    For arrays a kernel reads or writes one pose (one column) at a time, down
    dozens of rows: rows a multiple of 4 KiB apart (``n`` a multiple of 1,024
    float32) all fall in one set of the L1 cache and evict each other, which
    made the kinematics kernel five times slower at 4,096 poses than at 4,000.
    With an odd number of 64-byte lines between rows, 64 rows fall in 64
    different sets. A plain contiguous array when the kernels are off.
    """
    if not ENABLED:
        return np.empty(lead + (n,), dtype)
    per_line = 64 // np.dtype(dtype).itemsize
    lines = -(-n // per_line)
    lines += 1 - lines % 2
    return np.empty(lead + (lines * per_line,), dtype)[..., :n]


def padded_rows(array: NDArray) -> NDArray:
    """A C-contiguous array whose ``[..., :n]`` is ``array`` (``n`` its last axis).

    The whole buffer of a :func:`spaced_rows` array (no copy), which a kernel
    looping over its last axis can take as contiguous rows: numba compiles
    loops over a non-contiguous array's rows without vector instructions (the
    cones' image bases ran 1.9 times slower on the spaced keypoints than on a
    contiguous copy). Any other array comes back C-contiguous (a copy where
    it is not already).
    """
    if array.flags.c_contiguous:
        return array
    base = array.base
    if (
        isinstance(base, np.ndarray)
        and base.flags.c_contiguous
        and base.dtype == array.dtype
        and base.shape[:-1] == array.shape[:-1]
        and base.strides == array.strides
        and base.ctypes.data == array.ctypes.data
    ):
        return base
    return np.ascontiguousarray(array)


@functools.cache
def compiled() -> ModuleType:
    """The kernels' module, numba imported (once, on the first call)."""
    return importlib.import_module("humotion_gym._numba_kernels")


#: What :func:`_call` returns when numba failed.
_FAILED = object()


def _call(kernel: str, *args: Any) -> Any:
    """Run a kernel and return its result; :data:`_FAILED` when numba fails.

    A failure turns the kernels off, with a warning.

    numba compiles each kernel on its first call (or loads it from its cache).
    A numba that cannot (one older or newer than this numpy supports, a
    broken cache) should cost speed, not the run: the numpy path gives the
    same numbers.
    """
    global ENABLED
    try:
        return getattr(compiled(), kernel)(*args)
    except Exception as exc:  # noqa: BLE001 (any failure of numba falls back)
        ENABLED = False
        warnings.warn(
            f"humotion_gym: the compiled kernels (the `fast` extra) failed ({type(exc).__name__}: "
            f"{exc}); the numpy path runs instead, with the same numbers. HUMOTION_NUMBA=0 "
            "skips them.",
            RuntimeWarning,
            stacklevel=4,
        )
        return _FAILED


def _run(kernel: str, *args: Any) -> bool:
    """Run a kernel that fills its arguments; False when the kernels are off or numba failed.

    (See :func:`_call`.)
    """
    return ENABLED and _call(kernel, *args) is not _FAILED


def _draws_here(rng: np.random.Generator) -> bool:
    """Whether a kernel may draw from ``rng`` itself: the kernels are on, it is numpy's."""
    return ENABLED and type(rng) is np.random.Generator


def point_costs(
    coef: NDArray[np.float32],
    columns: NDArray[np.float32],
    outline_map: NDArray[np.int32] | None,
    axis_map: NDArray[np.int32] | np.int32,
    cost: NDArray[np.uint8],
    width: int,
    height: int,
    n_out: int,
    total: NDArray[np.float64] | None = None,
) -> NDArray[np.uint16] | None:
    """The observation model's summed point costs per column, or None to use numpy.

    The kernel of :meth:`baselines.observation.ObservationModel._point_costs`
    (see there for the arguments, ``total`` included; ``width`` and ``height``
    are the padded table's). None when the kernels are off or there is a
    single column (whose product numpy computes another way; see the module's
    docstring).
    """
    if not ENABLED or columns.shape[1] < 2:
        return None
    k = columns.shape[1]
    out = np.empty(k, np.uint16)
    # Each column's map offsets, one per column (no copy where they already
    # are); one offset for all goes in as a number beside zeros.
    outline = _zeros(k) if outline_map is None else np.asarray(outline_map, np.int32)
    axis = np.asarray(axis_map, np.int32)
    base = 0
    if axis.ndim == 0:
        axis, base = _zeros(k), int(axis)
    if not _run(
        "_point_costs", coef, np.ascontiguousarray(columns, np.float32), outline, axis, base,
        cost, width, height, n_out, out, _NO_TOTAL if total is None else total,
    ):  # fmt: skip
        return None
    return out


#: ``total`` when the caller wants none (the kernels take an empty array).
_NO_TOTAL = np.zeros(0)


@functools.lru_cache(maxsize=4)
def _zeros(k: int) -> NDArray[np.int32]:
    """``k`` zero offsets, made once per size (only ever read)."""
    return np.zeros(k, np.int32)


def cone_basis(
    rot: NDArray[np.float32],
    trans: NDArray[np.float32],
    keypoints: NDArray[np.float32],
    near: np.float32,
    focal: np.float32,
    shift_u: np.float32,
    shift_u_behind: np.float32,
    shift_v: np.float32,
    cone_start: NDArray[np.intp],
    cone_end: NDArray[np.intp],
    radii: NDArray[np.float32],
    varying: list[tuple[int, tuple, tuple, float]],
    pad: np.float32,
    four_bins: bool,
    plane: int,
    uvz: NDArray[np.float32],
    basis: NDArray[np.float32],
    normals: NDArray[np.float32],
    outline: NDArray[np.int32],
) -> bool:
    """The cones' image bases (the kernel of ``ObservationModel._cone_basis``).

    Fills ``basis`` ``(8, 10, N)``, ``normals`` ``(2, 10, N)`` and, with
    ``four_bins``, ``outline`` ``(10, N)``; ``uvz`` ``(3, 15, N)`` is scratch.
    ``varying``: ``(cone, x axis, y axis, aspect)`` of the cones whose
    silhouette width varies with the pose. See
    :meth:`baselines.observation.ObservationModel._cone_basis` for the rest.

    Returns:
        False (the numpy path is to run) when the kernels are off or failed
        (:func:`_run`) or the keypoints are not float32.
    """
    if not ENABLED or keypoints.dtype != np.float32:
        return False
    n = keypoints.shape[2]
    vary_cone = np.array([v[0] for v in varying], np.intp)
    vary_axes = np.empty((len(varying), 2, 3, n), np.float32)
    for k, (_, ax, ay, _) in enumerate(varying):
        vary_axes[k, 0] = ax
        vary_axes[k, 1] = ay
    vary_aspect = np.array([v[3] for v in varying], np.float32)
    return _run(
        "_cone_basis", rot, trans, padded_rows(keypoints), near, focal, shift_u, shift_u_behind,
        shift_v,
        cone_start, cone_end, radii, vary_cone, vary_axes, vary_aspect, pad, four_bins, plane,
        uvz, basis, normals, outline,
    )  # fmt: skip


def pose_rows(
    params: NDArray, columns: NDArray[np.intp], out: NDArray[np.float32], limit: float
) -> bool | None:
    """Check the poses' bounds and fill the kinematics' parameter rows, in one pass.

    ``params`` ``(N, P)`` C-contiguous float64 or float32; ``out`` ``(R, N)``
    float32 (spaced rows or contiguous), ``out[r] = params[:, columns[r]]``
    with numpy's rounding cast, bit for bit.

    Returns:
        Whether every value lies in ``[-limit, limit]`` (a NaN does not);
        None (nothing written: numpy is to do both) when the kernels are off
        or failed, or the arrays are not of that kind.
    """
    if (
        not ENABLED
        or params.dtype not in (np.float32, np.float64)
        or not params.flags.c_contiguous
        or out.dtype != np.float32
        or out.shape != (columns.size, params.shape[0])
    ):
        return None
    answer = _call("_pose_rows", params, columns, padded_rows(out), float(limit))
    return None if answer is _FAILED else bool(answer)


def kinematics(
    a: NDArray,
    trig: NDArray,
    off: NDArray,
    head_length: np.floating,
    upper: NDArray,
    lower: NDArray,
    sign: NDArray,
    want_head_axes: bool,
    kp: NDArray,
) -> NDArray[np.float32] | None:
    """The batched kinematics after the sines and cosines (``kinematics._batch_kinematics``).

    ``trig`` ``(2, 22, N)``: the angles' cosines, then sines. Fills ``kp``
    ``(3, 15, N)``; see ``_batch_kinematics`` for the rest. The kernel takes
    the spaced rows' buffers (:func:`padded_rows`): on contiguous rows its
    loops over the poses vectorise.

    Returns:
        ``(4, 3, N)``: the torso's x and y axes, then the head's (filled with
        ``want_head_axes``); None (the numpy path is to run) when the kernels
        are off or failed (:func:`_run`) or the arrays are not float32.
    """
    if not ENABLED or kp.dtype != np.float32:
        return None
    n = a.shape[1]
    axes = spaced_rows((4, 3), n)
    rot = spaced_rows((9,), n)
    out = padded_rows(kp)  # a copy only where kp is neither contiguous nor spaced rows
    if not _run(
        "_kinematics", padded_rows(a), padded_rows(trig), off, head_length, upper.reshape(-1),
        lower.reshape(-1), sign.reshape(-1), want_head_axes, out, padded_rows(axes),
        padded_rows(rot), n,
    ):  # fmt: skip
        return None
    if out is not kp and out is not kp.base:
        kp[...] = out[..., :n]
    return axes


def coverage_sums(
    basis: NDArray[np.float32], cones: NDArray[np.intp], q: NDArray[np.float32], tau: np.float32
) -> NDArray[np.float64] | None:
    """Each pose's summed squared coverage distances (``ObservationModel._coverage_cost``).

    ``basis`` ``(8, 10, N)``, ``cones`` the free cones, ``q`` ``(3, F)``: see
    ``_coverage_cost``.

    Returns:
        ``(N,)`` float64, numpy's pairwise sums of each pose's ``F`` values;
        None when the kernels are off, there is no cone, or ``F`` is 1 (numpy's
        product is then ``sgemv``, which sums otherwise) or over
        :data:`PAIRWISE_BLOCK`: those are left to numpy.
    """
    if not ENABLED or len(cones) == 0 or not 2 <= q.shape[1] <= PAIRWISE_BLOCK:
        return None
    out = np.empty(basis.shape[2])
    if not _run(
        "_coverage_sums", np.ascontiguousarray(basis, np.float32), np.asarray(cones, np.intp),
        np.ascontiguousarray(q, np.float32), tau, out,
    ):  # fmt: skip
        return None
    return out


def residual_sums(
    p_x: NDArray[np.float32],
    p_y: NDArray[np.float32],
    d_x: NDArray[np.float32],
    d_y: NDArray[np.float32],
    inv_len2: NDArray[np.float32],
    q_x: NDArray[np.float32],
    q_y: NDArray[np.float32],
    tau2: np.float32,
) -> NDArray[np.float64] | None:
    """Each pose's summed squared residual distances (``ObservationModel._residual_cost``).

    The segments' ``(S, N)`` starts, directions and inverse squared lengths
    and the ``(E,)`` residual points: see ``_residual_cost``.

    Returns:
        ``(N,)`` float64, numpy's pairwise sums of each pose's ``E`` values;
        None when the kernels are off, there is no segment or ``E`` is over
        :data:`PAIRWISE_BLOCK`: those are left to numpy.
    """
    if not ENABLED or p_x.shape[0] == 0 or q_x.shape[0] > PAIRWISE_BLOCK:
        return None
    out = np.empty(p_x.shape[1])
    arrays = [np.ascontiguousarray(a, np.float32) for a in (p_x, p_y, d_x, d_y, inv_len2)]
    if not _run(
        "_residual_sums", *arrays, np.ascontiguousarray(q_x, np.float32),
        np.ascontiguousarray(q_y, np.float32), tau2, out,
    ):  # fmt: skip
        return None
    return out


def standard_normal(rng: np.random.Generator, shape: int | tuple[int, ...]) -> NDArray[np.float64]:
    """``rng.standard_normal(shape)``: the same values, and the generator left in the same state.

    numba's ``Generator.standard_normal`` is numpy's algorithm on numpy's bit
    generator (see ``_numba_kernels._standard_normal``), at about a quarter of
    the cost per draw; the priors draw tens of thousands a frame. Fewer than
    :data:`NORMAL_MIN_SIZE` draws, or a generator of another kind, go to
    numpy, as everything does when the kernels are off.
    """
    size = math.prod(shape) if isinstance(shape, tuple) else int(shape)
    if size < NORMAL_MIN_SIZE or not _draws_here(rng):
        return rng.standard_normal(shape)
    out = np.empty(shape)
    # numpy holds the bit generator's lock while it draws; so does this.
    with rng.bit_generator.lock:
        ran = _run("_standard_normal", rng, out.reshape(-1))
    # A numba that fails does so compiling, before it draws: numpy's draws
    # then come from the same state.
    return out if ran else rng.standard_normal(shape)


def generator(entropy: int | Sequence[int]) -> np.random.Generator:
    """``np.random.default_rng(entropy)``: the same bit generator state, in a third of the time.

    For a non-negative int or a flat sequence of them (anything else goes to
    numpy, as everything does when the kernels are off). numpy's
    :class:`~numpy.random.SeedSequence` spends about 6-8 us on small numpy
    arrays hashing a seed into a PCG64 state, more than an episode's own
    draws; :func:`_numba_kernels._seed_words` does the same word arithmetic
    (``tests/test_kernels.py`` compares the states), and numpy's ``PCG64``
    takes the words through its seed-sequence interface. The generator's
    ``bit_generator.seed_seq`` is then a :class:`_SeedWords`, which cannot
    ``spawn``: for the generators the package makes and keeps to itself.
    """
    if ENABLED:
        words = _entropy_words(entropy)
        if words is not None:
            return np.random.Generator(np.random.PCG64(_SeedWords(words)))
    return np.random.default_rng(entropy)


def _entropy_words(entropy: Any) -> NDArray[np.uint32] | None:
    """SeedSequence's 32-bit words of a non-negative int or a flat sequence of them; else None."""
    values = [entropy] if type(entropy) is int else entropy
    if not isinstance(values, (list, tuple)) or not values:
        return None
    words: list[int] = []
    for value in values:
        if type(value) is not int or value < 0:
            return None
        while True:  # least significant word first; 0 is one word
            words.append(value & 0xFFFFFFFF)
            value >>= 32
            if not value:
                break
    return np.array(words, np.uint32)


class _SeedWords(np.random.bit_generator.ISeedSequence):
    """A seed sequence of given entropy words whose states the compiled kernel draws."""

    __slots__ = ("_entropy",)

    def __init__(self, entropy: NDArray[np.uint32]) -> None:
        self._entropy = entropy

    def generate_state(self, n_words: int, dtype: Any = np.uint32) -> NDArray[Any]:
        """``SeedSequence.generate_state``: ``n_words`` words of ``dtype`` (uint32 or uint64)."""
        kind = np.dtype(dtype)
        if kind not in (np.dtype(np.uint32), np.dtype(np.uint64)):
            raise ValueError(f"generate_state: dtype must be uint32 or uint64, got {kind}")
        per = kind.itemsize // 4
        words = _call("_seed_words", self._entropy, int(n_words) * per)
        if words is _FAILED:  # numba failed: numpy's own hash
            entropy = self._entropy.tolist()
            return np.random.SeedSequence(entropy).generate_state(n_words, dtype)
        return words.view(kind)


def cost_table(*args: Any) -> bool:
    """``ObservationModel.prepare``'s quantised cost maps (see ``_numba_kernels._cost_table``).

    The arguments are the kernel's; the distances and the table are written
    in place. The same bytes as the numpy path (``tests/test_kernels.py``).

    Returns:
        False (the numpy path is to run) when the kernels are off or failed.
    """
    return _run("_cost_table", *args)


def border_median(smooth: NDArray[np.uint8], b: int) -> NDArray[np.float64] | None:
    """``np.median`` of each channel over the frame's border ``b`` wide, from value counts.

    The values are bytes, so the two middle ones come from counts of each
    value (``_numba_kernels._border_median``), and their mean is numpy's: the
    same float64 (``tests/test_kernels.py``), in a tenth of ``np.median``'s
    time.

    Returns:
        ``(C,)`` float64; None when the kernels are off or failed, or ``b`` is
        under 1 (numpy's slices then take the whole frame).
    """
    if not ENABLED or b < 1:
        return None
    channels = smooth.shape[2]
    out = np.empty(channels)
    if not _run("_border_median", smooth, b, np.empty((4, channels, 256), np.int64), out):
        return None
    return out


def colour_distances(*args: Any) -> bool:
    """``ObservationModel._foreground``'s colour distances (``_numba_kernels._colour_distances``).

    Returns:
        False (the numpy path is to run) when the kernels are off or failed.
    """
    return _run("_colour_distances", *args)


def foreground_map(*args: Any) -> bool:
    """``ObservationModel._foreground``'s probability map (see ``_numba_kernels._foreground_map``).

    Returns:
        False (the numpy path is to run) when the kernels are off or failed.
    """
    return _run("_foreground_map", *args)


def canny_gradients(
    smooth: NDArray[np.uint8],
) -> tuple[NDArray[np.int16], NDArray[np.int16]] | None:
    """The Sobel gradients ``cv2.Canny`` picks from a colour frame, for ``cv2.Canny(dx, dy, ...)``.

    OpenCV's Canny of a three-channel image spends most of its time choosing,
    per pixel, the channel with the strongest gradient (about 160 us at
    128x128, against 20 us for the rest); the kernel
    (``_numba_kernels._canny_gradients``) makes the same choice in about 30.

    Args:
        smooth: ``(H, W, 3)`` uint8.

    Returns:
        ``(H, W)`` int16 ``dx`` and ``dy``; None when the kernels are off or
        failed.
    """
    if not ENABLED:
        return None
    h, w, _ = smooth.shape
    dx, dy = np.empty((h, w), np.int16), np.empty((h, w), np.int16)
    planes = np.empty((3, h + 2, w + 2), np.float32)
    if not _run("_canny_gradients", np.ascontiguousarray(smooth), dx, dy, planes):
        return None
    return dx, dy


#: OpenCV's steps of the 5x5 chamfer for ``DIST_L2`` (straight, diagonal,
#: knight's move), in float32 as its ``getDistanceTransformMask`` gives them.
CHAMFER_STEPS = (np.float32(1.0), np.float32(1.4), np.float32(2.1969))

#: The largest distance :func:`distance_maps` is asked to give exactly. The
#: kernel's float32 sums are OpenCV's (the IPP build the wheels ship) on every
#: map tried at every distance below 32.7 pixels; above, the two round a tie
#: differently now and then. Half of that leaves a margin.
DISTANCE_LIMIT = 16.0


def distance_maps(
    maps: NDArray[np.uint8], found: NDArray[np.bool_], steps: int, dist: NDArray[np.float32]
) -> bool:
    """``cv2.distanceTransform(map, DIST_L2, DIST_MASK_5)`` of each map, exact up to ``steps``.

    The kernel (``_numba_kernels._distance_maps``) gives OpenCV's float32
    distance at every pixel where that is at most ``steps`` and a larger one
    where it is larger, which a caller that truncates below ``steps`` cannot
    tell apart. Four 128x128 maps take about a third of OpenCV's time.

    Args:
        maps: ``(B, H, W)`` uint8, 0 at the edge pixels.
        found: ``(B,)`` whether each map has an edge pixel (those without are
            set to infinity, as the numpy path sets them).
        steps: The largest distance that must be exact, a whole number of
            pixels from 1 to :data:`DISTANCE_LIMIT`.
        dist: ``(B, H, W)`` float32, written.

    Returns:
        False (OpenCV is to run) when the kernels are off or failed, or
        ``steps`` is out of that range.
    """
    if not ENABLED or not 1 <= steps <= DISTANCE_LIMIT:
        return False
    _, h, w = maps.shape
    temp = np.empty((h + 4, w + 4), np.float32)
    pre = np.empty(w + 2 * steps, np.float32)
    v = np.empty(w, np.float32)
    hv, diag, knight = CHAMFER_STEPS
    return _run(
        "_distance_maps", np.ascontiguousarray(maps), np.ascontiguousarray(found), hv, diag,
        knight, steps, dist, temp, pre, v,
    )  # fmt: skip


def orientation_maps(
    smooth: NDArray[np.uint8], edges: NDArray[np.uint8], n_bins: int
) -> tuple[NDArray[np.uint8], NDArray[np.bool_]] | None:
    """``ObservationModel._oriented_edges``' orientation maps, from the gradients at the edges.

    ``_numba_kernels._edge_gradients`` lists the edge pixels and the
    strongest channel's Sobel gradient at each (the numpy path filters the
    whole frame twice); numpy's own ``arctan2`` turns them into angles (its
    vectorised float32 arctangent differs from the C library's, which numba
    would call, in the last bit of four angles in ten); and
    ``_numba_kernels._orientation_maps`` puts each pixel into its two bins.

    Args:
        smooth: ``(H, W, C)`` uint8, the blurred frame.
        edges: ``(H, W)`` uint8, its edge map (nonzero at edges).
        n_bins: The number of orientation bins, at least 2.

    Returns:
        ``(B, H, W)`` uint8 maps (0 at each bin's edge pixels, 255 elsewhere)
        and ``(B,)`` whether each bin holds an edge pixel, the numpy path's;
        None when the kernels are off or failed.
    """
    if not ENABLED:
        return None
    h, w, _ = smooth.shape
    n = int(np.count_nonzero(edges))
    ys, xs = np.empty(n, np.intp), np.empty(n, np.intp)
    gx, gy = np.empty(n, np.float32), np.empty(n, np.float32)
    smooth, edges = np.ascontiguousarray(smooth), np.ascontiguousarray(edges)
    written = _call("_edge_gradients", smooth, edges, ys, xs, gx, gy)
    if written is _FAILED:
        return None
    if written != n:  # (count_nonzero and the kernel's scan count the same pixels)
        raise RuntimeError(f"orientation_maps: {written} edge pixels scanned, {n} counted")
    theta = np.arctan2(gy, gx)  # gradient = outline normal
    maps = np.empty((n_bins, h, w), np.uint8)
    counts = np.empty(n_bins, np.int64)
    half_turn, per_bin = np.float32(np.pi), np.float32(n_bins / np.pi)
    if not _run("_orientation_maps", theta, ys, xs, half_turn, per_bin, maps, counts):
        return None
    return maps, counts > 0


def clutter_plan(
    rng: np.random.Generator,
    h: int,
    w: int,
    size: int,
    shape_rate: float,
    line_rate: float,
    thickness_unit: int,
) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]] | None:
    """``render._clutter_plan``'s arrays, drawn by numba from the same generator.

    numba's ports of numpy's ``poisson``, ``integers``, ``uniform``, ``random``
    and ``normal`` make the same draws from the same bit generator, so the
    plan and the generator's state afterwards are numpy's
    (``tests/test_kernels.py``; the renderer also checks it once,
    ``render._kernel_plans_as_numpy``).

    Returns:
        ``(shapes, shape_floats, lines)``; None (the numpy path is to run) when
        the kernels are off or failed, or ``rng`` is not a ``Generator``.
    """
    if not _draws_here(rng):
        return None
    with rng.bit_generator.lock:
        out = _call("_clutter_plan", rng, h, w, size, shape_rate, line_rate, thickness_unit)
    # A numba that fails does so compiling, before it draws.
    return None if out is _FAILED else out


def env_keypoints(
    params: NDArray[np.float64],
    torso: NDArray[np.float64],
    head: NDArray[np.float64],
    limbs: NDArray[np.float64],
    sign: NDArray[np.float64],
    rows: NDArray[np.intp],
) -> NDArray[np.float64] | None:
    """The vector environment's keypoints of N poses (``envs.vector._keypoints``).

    Returns:
        ``(N, 15, 3)``, the numpy path's numbers (``tests/test_kernels.py``);
        None (the numpy path is to run) when the kernels are off or failed.
    """
    if not ENABLED:
        return None
    out = np.empty((params.shape[0], 15, 3))
    args = (params, torso, head, limbs, sign, rows)
    contiguous = [np.ascontiguousarray(a, np.float64) for a in args[:5]]
    if not _run("_env_keypoints", *contiguous, np.ascontiguousarray(rows, np.intp), out):
        return None
    return out


def env_scores(
    params: NDArray[np.float64],
    truth_kp: NDArray[np.float64],
    k: NDArray[np.intp],
    actions: NDArray[Any],
    free: NDArray[np.intp],
    lo: NDArray[np.float64],
    hi: NDArray[np.float64],
    shape_table: tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]],
    sign: NDArray[np.float64],
    rows: NDArray[np.intp],
    scored: NDArray[np.intp],
    anchor: int,
) -> tuple[NDArray[np.float64], ...] | None:
    """The vector environment's step scores (``envs.vector._numpy_scores``) in one pass.

    ``params`` ``(N, F, 25)`` and ``truth_kp`` ``(N, F, 15, 3)`` the
    episodes' poses and keypoints, ``k`` the frame each scores, ``actions``
    ``(N, A)`` (any real dtype), ``shape_table`` the episodes' ``(torso,
    head, limbs)``; the rest as :func:`_numba_kernels._env_scores` takes them.

    Returns:
        ``(estimate, keypoints, errors, scored_errors, means)``, the numpy
        path's numbers (``tests/test_kernels.py``); None (the numpy path is
        to run) when the kernels are off or failed.
    """
    if not ENABLED:
        return None
    n = params.shape[0]
    out = (
        np.empty((n, params.shape[2])),
        np.empty((n, truth_kp.shape[2], 3)),
        np.empty((n, truth_kp.shape[2])),
        np.empty((n, scored.shape[0])),
        np.empty((n, 3)),
    )
    torso, head, limbs = (np.ascontiguousarray(a, np.float64) for a in shape_table)
    ran = _run(
        "_env_scores", params, truth_kp, np.ascontiguousarray(k, np.intp),
        np.ascontiguousarray(actions, np.float64), free, lo, hi, torso, head, limbs, sign, rows,
        scored, anchor, *out,
    )  # fmt: skip
    return out if ran else None


def region_sums(
    per_kp: NDArray[np.float64], members: NDArray[np.intp], bounds: NDArray[np.intp]
) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
    """The vector environment's reward terms by region and their sum (``envs.vector``).

    Returns:
        ``(terms, reward)``, ``(R, N)`` and ``(N,)``: the numpy path's numbers
        (each a chain of additions in a fixed order; ``tests/test_kernels.py``);
        None (the numpy path is to run) when the kernels are off or failed.
    """
    if not ENABLED:
        return None
    terms = np.empty((bounds.shape[0] - 1, per_kp.shape[0]))
    reward = np.empty(per_kp.shape[0])
    if not _run("_region_sums", np.ascontiguousarray(per_kp), members, bounds, terms, reward):
        return None
    return terms, reward


def paint_texture(*args: Any) -> bool:
    """``render._paint_texture``'s stripes or checks (see ``_numba_kernels._paint_texture``).

    The arguments are the kernel's; ``region`` is written in place. The same
    pixels as the numpy path (``tests/test_kernels.py``).

    Returns:
        False (the numpy path is to run) when the kernels are off or failed.
    """
    return _run("_paint_texture", *args)


def add_noise(img: NDArray[np.uint8], bank: NDArray[np.uint8], y: int, x: int) -> bool:
    """``render._add_noise``'s window of the noise bank added, then subtracted, saturating.

    ``img`` ``(H, W, C)`` (or ``(H, W)``), C-contiguous; ``bank`` ``(2, 2 H,
    2 W, C)``; the window at row ``y``, column ``x``. The same bytes as
    OpenCV's ``add`` and ``subtract`` (``tests/test_kernels.py``), in one pass.

    Returns:
        False (the numpy path is to run) when the kernels are off or failed,
        or the arrays are not C-contiguous or the window does not fit (where
        OpenCV then says what is wrong).
    """
    if not (ENABLED and img.flags.c_contiguous and bank.flags.c_contiguous and bank.ndim == 4):
        return False
    h, w = img.shape[:2]
    _, rows, cols, c = bank.shape
    if img.size != h * w * c or not (0 <= y <= rows - h and 0 <= x <= cols - w):
        return False
    flat = img.reshape(h, -1)
    return _run("_add_noise", flat, bank[0].reshape(rows, -1), bank[1].reshape(rows, -1), y, x * c)


def clutter_shapes(
    img: NDArray[np.uint8],
    shapes: NDArray[np.int64],
    floats: NDArray[np.float64],
    colors: NDArray[np.uint8],
    sin_table: NDArray[np.float32],
) -> bool:
    """Draw a clutter plan's shapes into ``img`` as ``render._draw_clutter`` does with OpenCV.

    ``img`` ``(H, W, C)`` uint8, written in place; ``shapes`` and ``floats``
    a :class:`~humotion_gym.render.ClutterPlan`'s, ``colors`` ``(S, 2, C)``
    uint8 each shape's colour (and a texture's second), ``sin_table``
    OpenCV's table of whole-degree sines (451 float32). The kernel is OpenCV's
    rectangle, ellipse and convex polygon fills in the same integer steps and
    the texture painter's float32 steps, so the pixels are OpenCV's
    (``tests/test_kernels.py``; the renderer checks it against the installed
    OpenCV once, ``render._kernel_clutter_as_opencv``).

    Returns:
        False (OpenCV is to draw) when the kernels are off or failed.
    """
    return _run("_clutter_shapes", img, shapes, floats, colors, sin_table)


def draw_figure(
    img: NDArray[np.uint8],
    ellipses: NDArray[np.int32],
    quads: NDArray[np.int32],
    colors: NDArray[np.uint8],
    order: NDArray[np.intp],
    wide: NDArray[np.bool_],
    shift: int,
) -> bool:
    """Draw one frame's cone figure into ``img`` (``render._draw_figure``'s OpenCV calls).

    ``img`` ``(H, W, C)`` uint8, written in place; one frame's ``ellipses``
    ``(10, 2K, 2)``, ``quads`` ``(10, S, 4, 2)`` and ``colors`` ``(10, 2 + S,
    C)`` of a :class:`~humotion_gym.render.FigureSequence`, the cones to draw
    in ``order`` and which are ``wide``; vertices with ``shift`` fractional
    bits. The kernel is OpenCV's convex hull and 8-connected convex polygon
    fill in the same integer steps, so the pixels are OpenCV's
    (``tests/test_kernels.py`` compares them; the renderer checks it against
    the installed OpenCV once, ``render._kernel_draws_as_opencv``).

    Returns:
        False (OpenCV is to draw) when the kernels are off or failed.
    """
    return _run("_draw_figure", img, ellipses, quads, colors, order, wide, shift)


def draw_frames(*args: Any) -> bool:
    """Several episodes' frames in one call (``render.FrameBatch``).

    The arguments are ``_numba_kernels._draw_frames``'. Each frame is ``render._compose``'s, byte
    for byte (``tests/test_kernels.py``).

    Returns:
        False (the frames are to be drawn one by one) when the kernels are off or failed.
    """
    return _run("_draw_frames", *args)


def halve_frames(frames: NDArray[np.uint8], out: NDArray[np.uint8]) -> bool:
    """Frames ``(N, H, W, C)`` shrunk by two into ``out`` ``(N, C, H / 2, W / 2)``, channels first.

    The bytes of OpenCV's ``resize`` with ``INTER_AREA`` (each 2x2 block's
    mean, rounded half up), transposed (``_numba_kernels._halve_frames``;
    ``wrappers.learner_frames`` checks it against the installed OpenCV once).

    Returns:
        False (OpenCV is to shrink them) when the kernels are off or failed,
        or the shapes are not a shrink by two of C-contiguous uint8 frames.
    """
    if not (ENABLED and frames.ndim == 4 and frames.dtype == np.uint8 and out.dtype == np.uint8):
        return False
    n, h, w, c = frames.shape
    if h % 2 or w % 2 or out.shape != (n, c, h // 2, w // 2):
        return False
    if not (frames.flags.c_contiguous and out.flags.c_contiguous):
        return False
    return _run("_halve_frames", frames, out)


def figure_polygons(*args: Any) -> bool:
    """``render._figure_polygons``' arrays from a kernel (see ``_numba_kernels._figure_polygons``).

    The arguments are the kernel's, outputs last, filled in place. The same
    numbers as the numpy path (``tests/test_kernels.py``).

    Returns:
        False (the numpy path is to run) when the kernels are off or failed.
    """
    return _run("_figure_polygons", *args)


def paced_path(
    history: NDArray[Any], speed: NDArray[np.float64], ix: int, iy: int, yaw: int
) -> NDArray[np.float64] | None:
    """``tree._paced_path``: the root path at the database's pace, in the heading frame.

    Returns:
        ``(N, d + 1, 2)`` the turned path (``tree._coefficients``' ``turned``),
        the numpy path's numbers; None when the kernels are off or failed.
    """
    if not ENABLED:
        return None
    heading = -np.asarray(history[:, -1, yaw], dtype=np.float64)
    turned = np.empty(history.shape[:2] + (2,))
    if not _run(
        "_paced_path", np.ascontiguousarray(history), np.ascontiguousarray(speed, np.float64),
        ix, iy, np.cos(heading), np.sin(heading), turned,
    ):  # fmt: skip
        return None
    return turned


def last_pose_distances(
    frames: NDArray[Any],
    window_end: NDArray[np.intp],
    columns: NDArray[np.intp],
    pose: NDArray[np.float64],
    scale: NDArray[np.float64],
) -> NDArray[np.float64] | None:
    """``tree._last_pose_distances``: each window's last pose's scaled squared distance.

    Args:
        frames: ``(M, D)`` the database's poses (either memory order).
        window_end: ``(W,)`` each window's last frame.
        columns: ``(K,)`` the parameters compared, in the order summed.
        pose: ``(K,)`` their values in the pose.
        scale: ``(K,)`` their scales.

    Returns:
        ``(W,)`` the numpy path's numbers; None when the kernels are off or failed.
    """
    if not ENABLED:
        return None
    dist2 = np.zeros(window_end.shape[0])
    if not _run(
        "_last_pose_distances", frames, np.ascontiguousarray(window_end, np.intp),
        np.ascontiguousarray(columns, np.intp), np.ascontiguousarray(pose, np.float64),
        np.ascontiguousarray(scale, np.float64), dist2,
    ):  # fmt: skip
        return None
    return dist2


def initial_histories(
    frames: NDArray[np.float64],
    ends: NDArray[np.intp],
    d: int,
    relative: NDArray[np.intp],
    root_xy: tuple[int, int] | None,
    anchor_heading: NDArray[np.float64] | None,
    speed: NDArray[np.float64] | None,
    pose: NDArray[np.float64],
    place_heading: NDArray[np.float64] | None,
    dtype: type[np.floating],
) -> NDArray[Any] | None:
    """``tree.initial``'s histories: windows gathered, anchored, paced and placed at a pose.

    Args:
        frames: ``(M, D)`` the database's poses, double precision.
        ends: ``(N,)`` each particle's window's last frame.
        d: Frames before the last in a window.
        relative: Positions of the relative parameters.
        root_xy: Positions of root x and y, turned by the headings (None: not turned).
        anchor_heading: Minus each window's last heading (what
            ``tree._anchor`` turns by), as numpy gives it.
        speed: ``(N,)`` each particle's speed, or None.
        pose: ``(D,)`` the pose the histories end at.
        place_heading: The pose's heading per particle (what ``tree._place``
            turns by), as numpy gives it.
        dtype: The histories' precision.

    Returns:
        ``(N, d + 1, D)`` the numpy path's histories; None when the kernels
        are off or failed.
    """
    if not ENABLED or frames.dtype != np.float64:
        return None
    n = ends.shape[0]
    out = np.empty((n, d + 1, frames.shape[1]), dtype)
    ix, iy = root_xy if root_xy is not None else (-1, -1)
    none = np.empty(0)
    trig = []
    for angle in (anchor_heading, place_heading):
        if root_xy is None or angle is None:
            trig += [none, none]
        else:
            trig += [
                np.ascontiguousarray(np.cos(angle).reshape(n)),
                np.ascontiguousarray(np.sin(angle).reshape(n)),
            ]
    if not _run(
        "_initial_histories", frames, np.ascontiguousarray(ends, np.intp),
        np.ascontiguousarray(relative, np.intp), ix, iy, trig[0], trig[1],
        none if speed is None else np.ascontiguousarray(speed, np.float64),
        np.ascontiguousarray(pose, np.float64), trig[2], trig[3], out,
    ):  # fmt: skip
        return None
    return out


def leaf_log_weights(
    database: NDArray[np.float64],
    probes: NDArray[np.float64],
    lo: NDArray[np.intp],
    sizes: NDArray[np.intp],
    starts: NDArray[np.intp],
    sigma: NDArray[np.float64],
    factor: float,
    total: int,
) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
    """``tree._leaf_log_weights``: eq. 3's exponents in each leaf, less the leaf's largest.

    Returns:
        ``(total,)`` the exponents and ``(N,)`` each leaf's largest, the numpy
        path's numbers; None when the kernels are off or failed.
    """
    if not ENABLED:
        return None
    logw = np.empty(total)
    peak = np.empty(lo.size)
    if not _run(
        "_leaf_log_weights", np.ascontiguousarray(database, np.float64),
        np.ascontiguousarray(probes, np.float64), np.ascontiguousarray(lo, np.intp),
        np.ascontiguousarray(sizes, np.intp), np.ascontiguousarray(starts, np.intp),
        np.ascontiguousarray(sigma, np.float64), float(factor), logw, peak,
    ):  # fmt: skip
        return None
    return logw, peak


def leaf_draws(
    cum: NDArray[np.float64],
    starts: NDArray[np.intp],
    sizes: NDArray[np.intp],
    lo: NDArray[np.intp],
    u: NDArray[np.float64],
) -> tuple[NDArray[np.intp], NDArray[np.float64]] | None:
    """``tree._leaf_draws``: each leaf's inverse-CDF draw on one running sum of weights.

    Returns:
        ``(N,)`` the chosen windows and each leaf's mass, the numpy path's
        numbers; None when the kernels are off or failed.
    """
    if not ENABLED:
        return None
    chosen = np.empty(lo.size, np.intp)
    mass = np.empty(lo.size)
    if not _run(
        "_leaf_draws", np.ascontiguousarray(cum, np.float64), np.ascontiguousarray(starts, np.intp),
        np.ascontiguousarray(sizes, np.intp), np.ascontiguousarray(lo, np.intp),
        np.ascontiguousarray(u, np.float64), chosen, mass,
    ):  # fmt: skip
        return None
    return chosen, mass


def tree_descend(
    coefficients: NDArray[np.float64],
    scale: NDArray[np.float64],
    rng: np.random.Generator,
    tables: tuple[NDArray[np.intp], ...],
    offsets: NDArray[np.intp],
) -> tuple[NDArray[np.intp], NDArray[np.intp]] | None:
    """``tree._descend`` (eq. 7) without the log probability: the probes' leaves.

    Args:
        coefficients: ``(N, b)`` the probes.
        scale: ``(b,)`` ``sqrt(beta) sigma``.
        rng: Draws numpy's ``(b, N)`` normals, in their order.
        tables: ``tree._packed_tables``: the descent tables end to end, each
            table's start, first level and levels.
        offsets: The tree's leaf offsets.

    Returns:
        ``[lo, hi)`` per probe, the numpy path's leaves with the generator left
        where numpy leaves it; None (nothing drawn) when the kernels are off,
        failed or the generator is not numpy's.
    """
    if not _draws_here(rng):
        return None
    n = coefficients.shape[0]
    lo, hi = np.empty(n, np.intp), np.empty(n, np.intp)
    with rng.bit_generator.lock:
        ran = _run(
            "_tree_descend", np.ascontiguousarray(coefficients, np.float64),
            np.ascontiguousarray(scale, np.float64), rng, *tables,
            np.ascontiguousarray(offsets, np.intp), lo, hi,
        )  # fmt: skip
    return (lo, hi) if ran else None


def tree_replay(
    next_step: NDArray[np.float64],
    chosen: NDArray[np.intp],
    pose: NDArray[np.float64],
    velocity: tuple[NDArray[Any], NDArray[np.intp], NDArray[np.bool_]] | None,
    speed: NDArray[np.float64] | None,
    root_xy: tuple[int, int] | None,
    rng: np.random.Generator,
    noise_std: NDArray[np.float64] | None,
    relative: NDArray[np.bool_],
    heading: NDArray[np.float64] | None,
    history: NDArray[Any],
    rows: NDArray[np.intp] | None = None,
) -> tuple[NDArray[np.float64], NDArray[Any]] | None:
    """``tree.transition`` after the choice of windows: the new poses and shifted histories.

    Args:
        next_step: ``(n, D)`` the database's next steps.
        chosen: ``(N,)`` the chosen windows.
        pose: ``(N, D)`` the particles' poses.
        velocity: ``(frames, window_end, absolute)`` for the velocity replay, else None.
        speed: ``(N,)`` the particles' speeds, or None.
        root_xy: Root x and y's columns where the root path is turned, else None.
        rng: Draws numpy's ``(N, D)`` normals where ``noise_std`` is given.
        noise_std: ``(D,)`` the noise's scale, or None for no noise.
        relative: ``(D,)`` True for the parameters that move relative to the pose.
        heading: ``(N,)`` the poses' headings (with ``root_xy``).
        history: ``(N, d + 1, D)`` the particles' histories, or with ``rows``
            ``(M, d + 1, D)`` histories of which particle ``p`` has row ``rows[p]``.
        rows: ``(N,)`` rows of ``history`` (resampled particles), or None.

    Returns:
        The numpy path's poses and histories (the generator left where numpy
        leaves it); None (nothing drawn) when the kernels are off, failed or
        the generator is not numpy's.
    """
    if not _draws_here(rng):
        return None
    n, dim = pose.shape
    empty = np.zeros(0)
    frames, window_end, absolute = (
        velocity if velocity is not None else (np.zeros((1, dim)), np.zeros(1, np.intp), relative)
    )
    ix, iy = root_xy if root_xy is not None else (-1, -1)
    cos_h = sin_h = empty
    if root_xy is not None:
        assert heading is not None
        cos_h, sin_h = np.cos(heading), np.sin(heading)
    speeds = empty if speed is None else np.ascontiguousarray(speed, np.float64)
    scale = empty if noise_std is None else np.ascontiguousarray(noise_std, np.float64)
    out_pose = np.empty((n, dim))
    out_history = np.empty((n,) + history.shape[1:], history.dtype)
    index = _NO_ROWS if rows is None else np.ascontiguousarray(rows, np.intp)
    with rng.bit_generator.lock:
        ran = _run(
            "_tree_replay", np.ascontiguousarray(next_step, np.float64),
            np.ascontiguousarray(chosen, np.intp), np.ascontiguousarray(pose, np.float64), frames,
            np.ascontiguousarray(window_end, np.intp), np.ascontiguousarray(absolute, np.bool_),
            velocity is not None, speeds, ix, iy, rng, scale, noise_std is not None,
            np.ascontiguousarray(relative, np.bool_), cos_h, sin_h, np.ascontiguousarray(history),
            index, out_pose, out_history,
        )  # fmt: skip
    return (out_pose, out_history) if ran else None


#: ``tree_replay``'s rows when every particle reads its own history.
_NO_ROWS = np.zeros(0, np.intp)


def angle_offsets(
    particles: NDArray[np.float64],
    columns: NDArray[np.intp] | slice,
    centre: NDArray[np.float64],
) -> NDArray[np.float32] | None:
    """``filtering.weighted_mean``'s wrapped offsets of the angle columns from ``centre``.

    ``columns``: the angle columns' indices, or (where they are a run) their
    slice, through which the kernel reads each row as a slice.

    Returns:
        ``(N, number of columns)`` float32, the numpy path's numbers; None
        when the kernels are off or failed.
    """
    if not ENABLED:
        return None
    if isinstance(columns, slice):
        first, index = int(columns.start), np.arange(columns.start, columns.stop, dtype=np.intp)
    else:
        first, index = -1, np.ascontiguousarray(columns, np.intp)
    out = np.empty((particles.shape[0], index.size), np.float32)
    if not _run(
        "_angle_offsets", np.ascontiguousarray(particles, np.float64), index,
        np.ascontiguousarray(centre, np.float64), first, out,
    ):  # fmt: skip
        return None
    return out


def leaf_choice(
    database: NDArray[np.float64],
    probes: NDArray[np.float64],
    lo: NDArray[np.intp],
    hi: NDArray[np.intp],
    sigma: NDArray[np.float64],
    factor: float,
    rng: np.random.Generator,
) -> NDArray[np.intp] | None:
    """``tree._choose_weighted`` without the masses: one window per leaf ``[lo, hi)`` by eq. 3.

    The leaves of more than one window are found, their exponents formed and
    their windows drawn in two kernels; the exponentials between them are
    numpy's (its own SIMD ``exp``, which libm's would not match).

    Returns:
        ``(N,)`` the chosen windows, the numpy path's, with the generator left
        where numpy leaves it; None (nothing drawn) when the kernels are off,
        failed or the generator is not numpy's.
    """
    if not _draws_here(rng):
        return None
    lo = np.ascontiguousarray(lo, np.intp)
    made = _call(
        "_leaf_choice", np.ascontiguousarray(database, np.float64),
        np.ascontiguousarray(probes, np.float64), lo, np.ascontiguousarray(hi, np.intp),
        np.ascontiguousarray(sigma, np.float64), float(factor),
    )  # fmt: skip
    if made is _FAILED:
        return None
    logw, many, starts, sizes = made
    chosen = lo.copy()
    if many.size == 0:
        return chosen
    np.exp(logw, out=logw)
    with rng.bit_generator.lock:
        ran = _run("_leaf_choice_draws", logw, many, starts, sizes, lo, rng, chosen)
    return chosen if ran else None
