"""Saved parameters (``baselines.priors._io``) and the priors' shared checks, on tiny inputs."""

from __future__ import annotations

import dataclasses
import io
import struct
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from baselines.priors._checks import check_shapes, free_indices
from baselines.priors._io import load_fitted, open_npz, read_arrays, save_arrays, save_fitted
from baselines.priors._synthesis import check_request, model_frames, to_motion


@dataclasses.dataclass(frozen=True)
class _Params:
    """A prior's parameters in miniature: a one-element array, a vector, a scalar, a name."""

    one: np.ndarray
    vector: np.ndarray
    scale: float
    name: str

    def __post_init__(self) -> None:
        if not isinstance(self.scale, float):
            raise TypeError(f"scale must be a float, got {type(self.scale).__name__}")


def test_a_one_element_array_comes_back_an_array_and_a_scalar_a_scalar(tmp_path: Path) -> None:
    """Only 0-d arrays are read back as scalars: a ``(1,)`` field keeps its shape."""
    params = _Params(np.array([2.5]), np.array([1.0, 2.0]), 0.5, "walk")
    path = tmp_path / "p.npz"
    save_fitted(params, path, _Params)
    back = load_fitted(_Params, path)
    assert isinstance(back.one, np.ndarray) and back.one.shape == (1,)
    np.testing.assert_array_equal(back.one, [2.5])
    np.testing.assert_array_equal(back.vector, [1.0, 2.0])
    assert back.scale == 0.5 and isinstance(back.scale, float)
    assert back.name == "walk" and isinstance(back.name, str)


def test_a_type_the_class_refuses_is_a_value_error_naming_the_file(tmp_path: Path) -> None:
    """The class's own TypeError on load is a ValueError that names the file."""
    path = tmp_path / "p.npz"
    save_arrays(
        {
            "__kind__": np.array("_Params"),
            "one": np.array([1.0]),
            "vector": np.zeros(2),
            "scale": np.array(3),  # an integer where the class wants a float
            "name": np.array("x"),
        },
        path,
    )
    with pytest.raises(ValueError, match=r"p\.npz: scale must be a float"):
        load_fitted(_Params, path)


def test_an_array_of_python_objects_is_refused_and_nothing_is_written(tmp_path: Path) -> None:
    """``save_arrays`` never pickles: an object array is a TypeError and leaves no file."""
    path = tmp_path / "objects.npz"
    with pytest.raises(TypeError, match="'bad' is not an array of numbers or strings"):
        save_arrays({"good": np.zeros(2), "bad": np.array([{"a": 1}, None], dtype=object)}, path)
    assert list(tmp_path.iterdir()) == []


def test_an_optional_array_may_be_missing_and_a_required_one_may_not(tmp_path: Path) -> None:
    """``read_arrays``' ``optional`` names may be absent (older files); the others are refused."""
    path = tmp_path / "old.npz"
    save_arrays({"__kind__": np.array("X"), "a": np.arange(3.0)}, path)
    with open_npz(path, "X parameters") as data:
        got = read_arrays(data, path, {"a", "b"}, optional=frozenset({"b"}))
        assert set(got) == {"a"}
        np.testing.assert_array_equal(got["a"], [0.0, 1.0, 2.0])
        with pytest.raises(ValueError, match=r"the arrays \['b'\] are missing"):
            read_arrays(data, path, {"a", "b"})


def test_a_member_whose_compressed_data_is_damaged_is_named(tmp_path: Path) -> None:
    """A deflate stream broken at its start (zlib's error) is a ValueError naming the file."""
    buf = io.BytesIO()
    np.savez_compressed(buf, __kind__=np.array("X"), a=np.arange(1000.0))
    raw = bytearray(buf.getvalue())
    info = zipfile.ZipFile(io.BytesIO(bytes(raw))).getinfo("a.npy")
    # the local header: 30 bytes, then the name and its extra field (lengths at 26 and 28)
    name_len, extra_len = struct.unpack(
        "<HH", raw[info.header_offset + 26 : info.header_offset + 30]
    )
    start = info.header_offset + 30 + name_len + extra_len
    raw[start : start + 8] = b"\xff" * 8  # an invalid deflate block type
    path = tmp_path / "damaged.npz"
    path.write_bytes(bytes(raw))
    with pytest.raises(ValueError, match=r"damaged\.npz: damaged X parameters file"):
        with open_npz(path, "X parameters") as data:
            read_arrays(data, path, {"a"})


# ------------------------------------------------ the fits' and synthesis' shared checks


@pytest.mark.parametrize(
    "free",
    [np.array([], dtype=np.intp), [0, 25], [24, -1], [3, 3], [1.5], [[0, 1]]],
    ids=["empty", "25", "negative", "repeated", "fraction", "2-d"],
)
def test_free_indices_refuse_what_is_not_distinct_indices_in_range(free: object) -> None:
    """Every index in [0, 25), at least one, none twice, integers in a flat list."""
    with pytest.raises(
        ValueError, match=r"demo: free must be distinct integer indices in \[0, 25\)"
    ):
        free_indices(free, "demo")


def test_free_indices_take_the_edges_and_the_default() -> None:
    """0 and 24 are indices; None is the default given, else all 25."""
    np.testing.assert_array_equal(free_indices([24, 0], "demo"), [24, 0])
    np.testing.assert_array_equal(free_indices(None, "demo"), np.arange(25))
    arm = np.array([9, 10, 11, 12], dtype=np.intp)
    assert free_indices(None, "demo", default=arm) is arm


def test_check_shapes_takes_any_length_only_where_minus_one() -> None:
    """-1 matches any length; every other entry, 1 included, must match exactly."""
    check_shapes("P", {"a": np.zeros((7, 2)), "b": np.zeros(1)}, {"a": (-1, 2), "b": (1,)})
    for got, want in (((3, 2), (1, 2)), ((2,), (1,)), ((2, 2), (2,)), ((2,), (2, 1))):
        with pytest.raises(ValueError, match=r"P\.a has shape"):
            check_shapes("P", {"a": np.zeros(got)}, {"a": want})


@pytest.mark.parametrize(
    "frames, model_fps, fps, want",
    # the last output frame is at (frames - 1) / fps s, model frame (frames - 1) * model_fps / fps
    [
        (7, 10.0, 30.0, 3),
        (8, 10.0, 30.0, 4),
        (5, 30.0, 30.0, 5),
        (1, 30.0, 30.0, 2),
        (3, 60.0, 30.0, 5),
    ],
)
def test_model_frames_are_the_fewest_that_cover_the_output(
    frames: int, model_fps: float, fps: float, want: int
) -> None:
    """The fewest model frames reaching the last output frame's time, and at least 2."""
    assert model_frames(frames, model_fps, fps) == want
    # covering: the last model frame is at or after the last output frame; fewest: one less is not
    last = (frames - 1) * model_fps / fps
    assert want - 1 >= last and (want == 2 or want - 2 < last)


def test_to_motion_resamples_the_model_poses_in_time() -> None:
    """A model at 10 Hz read at 30 Hz: output frame k is model time k / 3, linearly."""
    base = np.arange(25, dtype=np.float64)
    free = np.array([4, 20])
    model = np.array([[0.0, 100.0], [3.0, 70.0], [6.0, 40.0]])  # linear ramps in model frames
    out = to_motion(base, free, model, 10.0, 7, 30.0)
    k = np.arange(7)
    np.testing.assert_allclose(out[:, 4], k, atol=1e-12)  # 3 per model frame, 1 per output frame
    np.testing.assert_allclose(out[:, 20], 100.0 - 10.0 * k, atol=1e-12)
    others = np.setdiff1d(np.arange(25), free)
    np.testing.assert_array_equal(out[:, others], np.repeat(base[None, others], 7, axis=0))


@pytest.mark.parametrize("fps", [0.0, -30.0, float("nan"), float("inf"), "30"])
def test_a_synthesis_request_needs_a_positive_rate(fps: object) -> None:
    """``fps`` must be a finite number above 0."""
    with pytest.raises(ValueError, match="fps must be a positive number"):
        check_request(np.zeros(25), 10, fps, np.random.default_rng(0))  # type: ignore[arg-type]


def _prior_members() -> list[Any]:
    """Each prior's load, the kind its files hold and the arrays it reads."""
    from baselines.priors import PRIORS, get_prior
    from baselines.priors.tree_fit import _DERIVED
    from baselines.priors.tree_model import TreeParams

    out = []
    for name in PRIORS:
        module = get_prior(name)
        cls = next(
            v for k, v in vars(module).items() if k.endswith("Params") and isinstance(v, type)
        )
        names = {f.name for f in dataclasses.fields(cls)}
        if cls is TreeParams:
            names = names - set(_DERIVED) | {"clip_lengths", "window_end"}
        out.append(pytest.param(name, cls.__name__, names, id=name))
    return out


def _npy(array: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.save(buf, array)
    return buf.getvalue()


@pytest.mark.parametrize(("prior", "kind", "names"), _prior_members())
@pytest.mark.parametrize(
    ("member", "says"),
    [
        (_npy(np.array([1, "a"], dtype=object)), "Object arrays cannot be loaded"),
        (b"\x93NUMPY\x09\x00 not a header", "format version"),
    ],
    ids=["objects", "header"],
)
def test_a_member_numpy_will_not_read_is_named_with_its_file(
    tmp_path: Path, prior: str, kind: str, names: set[str], member: bytes, says: str
) -> None:
    """An array of Python objects or a damaged ``.npy`` header: the file and the array named."""
    from baselines.priors import get_prior

    path = tmp_path / "edited.npz"
    with zipfile.ZipFile(path, "w") as z:
        z.writestr("__kind__.npy", _npy(np.array(kind)))
        z.writestr("__format__.npy", _npy(np.array("3")))
        for name in sorted(names):
            z.writestr(f"{name}.npy", member)
    with pytest.raises(ValueError, match=rf"edited\.npz: damaged {kind} file: its array '\w+'"):
        try:
            get_prior(prior).load(path)
        except ValueError as exc:
            assert says in str(exc)
            raise
