"""Property-based fuzzing (hypothesis) of actions, seeds and scenario configs.

Whatever a user passes, the envs either do the documented thing or raise a class of
``khepera_gym.errors`` whose message names the problem: no other exception type, no warning, no
Rust panic, no hang, and a rejected action leaves every world of a batch exactly as it was.

* actions, for the single env (``gym.make``, with Gymnasium's wrappers), the native vector env
  (``gym.make_vec``) and the raw ``_core.Batch``: arrays of every dtype (float16 to longdouble in
  both byte orders, ints, bools, complex, strings, datetimes, objects) and shape (0 to 3 dims),
  NaN/±inf/huge/subnormal values, non-contiguous layouts (strides, transposes, Fortran order,
  negative strides), read-only arrays, nested lists, scalars, None;
* seeds: ints of any size and sign, NumPy ints, bools, floats, strings, sequences (vector env);
* configs: keyword overrides of every scenario key (leaf, dotted and section forms) with plausible,
  impossible and ill-typed values and unknown keys; random TOML files; random config names.

Every env under test has a twin that only ever sees valid input: a valid action must give bit for
bit what the twin gives with the clipped float32 action in C order, and after a rejected input
the env must go on exactly like its twin (same observations, rewards, flags and poses).

Profiles, chosen by the ``HYPOTHESIS_PROFILE`` environment variable: "ci" (the default: few
examples, derandomized so that CI runs are reproducible) and "long" (``HYPOTHESIS_MAX_EXAMPLES``
examples per property, 4000 by default, random), e.g.::

    HYPOTHESIS_PROFILE=long pytest tests/test_fuzz.py --hypothesis-show-statistics

Regression tests: the end of this file holds a minimal repro of each bug this suite has found
(all fixed), so that each stays fixed whatever the random draws.
"""

from __future__ import annotations

import contextlib
import dataclasses
import faulthandler
import functools
import json
import math
import operator
import os
import re
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from conftest import LATEST
from hypothesis import HealthCheck, event, given, note, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from khepera_gym import _core
from khepera_gym.envs import NavEnv
from khepera_gym.errors import ActionError, ConfigError, KheperaError

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10: tomli, a dependency there
    import tomli as tomllib

# --- profiles ---------------------------------------------------------------------------------

_HEALTH = [HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.filter_too_much]
settings.register_profile(
    "ci",
    max_examples=100,
    deadline=None,
    derandomize=True,
    database=None,
    print_blob=True,
    suppress_health_check=_HEALTH,
)
settings.register_profile(
    "long",
    max_examples=int(os.environ.get("HYPOTHESIS_MAX_EXAMPLES", "4000")),
    deadline=None,
    database=None,
    print_blob=True,
    suppress_health_check=_HEALTH,
)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))

# --- helpers ----------------------------------------------------------------------------------

#: The latest id of every task with a Gymnasium env, from the registry, and each one's task.
ENV_IDS = tuple(LATEST.values())
TASKS = {env_id: task for task, env_id in LATEST.items()}
#: Worlds of the vector envs and batches under test.
N_VECTOR = 4
N_BATCH = 3
U64 = 2**64


@contextlib.contextmanager
def _watchdog(seconds: float = 120.0) -> Iterator[None]:
    """Kills the process, printing every thread's traceback, if an example hangs: a loop in Rust
    never returns to the interpreter, so no exception could stop it."""
    faulthandler.dump_traceback_later(seconds, exit=True)
    try:
        yield
    finally:
        faulthandler.cancel_dump_traceback_later()


def _attempt(call: Callable[[], Any]) -> tuple[Any, BaseException | None]:
    """Runs ``call`` with warnings as errors; returns (result, None) or (None, the exception)."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        try:
            return call(), None
        except (KeyboardInterrupt, SystemExit):
            raise
        except BaseException as error:  # pyo3's PanicException derives from BaseException
            return None, error


def _describe(error: BaseException | None) -> str:
    if error is None:
        return "no exception"
    return f"{type(error).__module__}.{type(error).__qualname__}: {error}"


def _assert_same(a: Any, b: Any, where: str = "") -> None:
    """Bit-for-bit equality of step/reset outputs (tuples, arrays, dicts, numbers)."""
    if isinstance(a, dict):
        assert isinstance(b, dict) and a.keys() == b.keys(), (where, a, b)
        for key in a:
            _assert_same(a[key], b[key], f"{where}[{key!r}]")
    elif isinstance(a, (tuple, list)):
        assert isinstance(b, (tuple, list)) and len(a) == len(b), (where, a, b)
        for index, (x, y) in enumerate(zip(a, b, strict=True)):
            _assert_same(x, y, f"{where}[{index}]")
    elif isinstance(a, np.ndarray):
        np.testing.assert_array_equal(a, b, err_msg=where, strict=True)
    else:
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b), err_msg=where)


def _assert_in_bounds(obs: np.ndarray, low: np.ndarray, high: np.ndarray) -> None:
    assert np.all(np.isfinite(obs)), f"non-finite observation {obs}"
    assert np.all(obs >= low) and np.all(obs <= high), f"observation {obs} outside [{low}, {high}]"


# --- environments under test and their twins --------------------------------------------------


@dataclasses.dataclass
class _Pair:
    """An env under test and its twin, which only ever sees valid input."""

    backend: str  # "single" (gym.make), "vector" (gym.make_vec) or "batch" (_core.Batch)
    env: Any
    twin: Any
    shape: tuple[int, ...]  # action shape
    low: np.ndarray
    high: np.ndarray

    @property
    def strict(self) -> bool:
        """The raw Batch takes float32 ndarrays only; the envs convert what NumPy can."""
        return self.backend == "batch"

    def reset(self, env: Any, seed: Any) -> Any:
        if self.backend == "batch":
            return env.reset(seed)
        return env.reset(seed=seed)[0]

    def reset_both(self, seed: int) -> None:
        _assert_same(self.reset(self.env, seed), self.reset(self.twin, seed), "reset")

    def step(self, env: Any, action: Any) -> tuple[Any, ...]:
        """(obs, reward, terminated, truncated) of one step."""
        return tuple(env.step(action)[:4])

    def poses(self, env: Any) -> np.ndarray:
        return env.poses() if self.backend == "batch" else env.unwrapped.poses()

    def step_both(self, action: np.ndarray) -> None:
        """Steps env and twin with the same valid action; they must agree bit for bit."""
        out, error = _attempt(lambda: self.step(self.env, action))
        assert error is None, f"valid action {action!r} failed: {_describe(error)}"
        _assert_same(out, self.step(self.twin, action), "step")
        _assert_same(self.poses(self.env), self.poses(self.twin), "poses")
        self.check_outputs(out)

    def check_outputs(self, out: tuple[Any, ...]) -> None:
        obs, reward, terminated, truncated = out
        _assert_in_bounds(obs, self.low, self.high)
        assert np.all(np.isfinite(reward)), f"non-finite reward {reward}"
        assert np.asarray(terminated).dtype == bool or isinstance(terminated, bool)
        assert np.asarray(truncated).dtype == bool or isinstance(truncated, bool)


def _make_pair(backend: str, env_id: str, max_steps: int | None) -> _Pair:
    overrides = {} if max_steps is None else {"max_steps": max_steps}
    if backend == "single":
        env, twin = (gym.make(env_id, **overrides) for _ in range(2))
        space = env.observation_space
        return _Pair(backend, env, twin, env.action_space.shape, space.low, space.high)
    if backend == "vector":
        # Different thread counts: results must not depend on them either.
        env = gym.make_vec(env_id, num_envs=N_VECTOR, num_threads=2, **overrides)
        twin = gym.make_vec(env_id, num_envs=N_VECTOR, num_threads=1, **overrides)
        space = env.single_observation_space
        return _Pair(backend, env, twin, env.action_space.shape, space.low, space.high)
    env, twin = (
        _core.Batch(TASKS[env_id], N_BATCH, overrides=overrides or None, num_threads=threads)
        for threads in (2, 1)
    )
    low, high = env.obs_bounds()
    return _Pair(backend, env, twin, (N_BATCH, env.act_dim), low, high)


#: Env/twin pairs, built once per module and reset by every example.
_PAIRS: dict[tuple[str, str, int | None], _Pair] = {}


def _get_pair(backend: str, env_id: str, max_steps: int | None = None) -> _Pair:
    key = (backend, env_id, max_steps)
    if key not in _PAIRS:
        _PAIRS[key] = _make_pair(*key)
    return _PAIRS[key]


@pytest.fixture(scope="module", autouse=True)
def _close_pairs() -> Iterator[None]:
    yield
    for pair in _PAIRS.values():
        if pair.backend != "batch":
            pair.env.close()
            pair.twin.close()
    _PAIRS.clear()


# --- action strategies ------------------------------------------------------------------------

_F32_MAX = float(np.finfo(np.float32).max)
_FLOAT_SIZES = (16, 32, 64, 128) if hasattr(np, "float128") else (16, 32, 64)
_NUMERIC_STRINGS = ("0", "1", "-1", "0.5", "-0.25", "7", "1e9", "nan", "inf", "", " ", "x")
_REAL_SCALARS = (bool, int, float, np.bool_, np.integer, np.floating)

_DTYPES = st.one_of(
    st.just(np.dtype(np.float32)),
    hnp.floating_dtypes(sizes=_FLOAT_SIZES, endianness="?"),
    hnp.integer_dtypes(endianness="?"),
    hnp.unsigned_integer_dtypes(endianness="?"),
    hnp.boolean_dtypes(),
    hnp.complex_number_dtypes(endianness="?"),
    hnp.unicode_string_dtypes(max_len=5),
    hnp.byte_string_dtypes(max_len=5),
    hnp.datetime64_dtypes(),
    hnp.timedelta64_dtypes(),
    st.just(np.dtype(object)),
)

#: Elements of object arrays and nested lists: numbers of every size, None, strings, ...
_OBJECTS = st.one_of(
    st.floats(-1.0, 1.0),
    st.floats(),
    st.integers(-3, 3),
    st.integers(),
    st.sampled_from([10**400, -(10**400), 2**64, -(2**63) - 1, 1e-320, -0.0]),
    st.booleans(),
    st.none(),
    st.sampled_from(_NUMERIC_STRINGS),
    st.text(max_size=3),
    st.binary(max_size=2),
    st.complex_numbers(max_magnitude=2.0),
    st.builds(np.float16, st.floats(-2.0, 2.0, width=16)),
    st.builds(np.uint64, st.integers(0, 2**64 - 1)),
)


def _elements(dtype: np.dtype) -> st.SearchStrategy[Any]:
    """Array elements: many plausible values next to everything NumPy can hold."""
    if dtype.kind == "f":
        width = min(dtype.itemsize * 8, 64)
        return st.one_of(
            st.floats(-1.0, 1.0, width=width),
            st.floats(-3.0, 3.0, width=width),
            hnp.from_dtype(dtype),
        )
    if dtype.kind == "O":
        return _OBJECTS
    if dtype.kind in "US":
        size = dtype.itemsize // (4 if dtype.kind == "U" else 1)
        numeric = st.sampled_from([s for s in _NUMERIC_STRINGS if len(s) <= size])
        if dtype.kind == "S":
            numeric = numeric.map(str.encode)
        return st.one_of(numeric, hnp.from_dtype(dtype))
    return hnp.from_dtype(dtype)


def _shapes(shape: tuple[int, ...]) -> st.SearchStrategy[tuple[int, ...]]:
    """The right shape (often), near misses, and any shape of 0 to 3 dimensions."""
    near = {
        (*shape[:-1], shape[-1] + 1),
        (*shape[:-1], shape[-1] - 1),
        (*shape, 1),
        (1, *shape),
        shape[::-1],
        shape[1:] or (1,),
        (shape[0] * shape[-1],),
    }
    return st.one_of(
        st.just(shape),
        st.just(shape),
        st.sampled_from(sorted(near)),
        hnp.array_shapes(min_dims=0, max_dims=3, min_side=0, max_side=6),
    )


_LAYOUTS = ("C", "F", "strided", "reversed", "transposed", "readonly", "list", "tuple")


def _relayout(array: np.ndarray, layout: str) -> Any:
    """The same values in another memory layout or container."""
    if layout == "F":
        return np.asfortranarray(array)
    if layout == "strided" and array.ndim:
        wide = np.empty((*array.shape[:-1], 2 * array.shape[-1]), dtype=array.dtype)
        wide[..., ::2] = array
        return wide[..., ::2]
    if layout == "reversed" and array.ndim:
        return np.ascontiguousarray(array[::-1])[::-1]
    if layout == "transposed":
        return np.ascontiguousarray(array.T).T
    if layout == "readonly":
        array = array.copy()
        array.flags.writeable = False
        return array
    if layout == "list":
        return array.tolist()
    if layout == "tuple" and array.ndim:
        return tuple(array.tolist())
    return array


@st.composite
def _arrays(draw: st.DrawFn, shape: tuple[int, ...]) -> Any:
    dtype = draw(_DTYPES)
    array = draw(hnp.arrays(dtype, _shapes(shape), elements=_elements(dtype)))
    return _relayout(array, draw(st.sampled_from(_LAYOUTS)))


@st.composite
def _plausible_arrays(draw: st.DrawFn, shape: tuple[int, ...]) -> Any:
    """Right shape, float32, mostly in range: these must be accepted in every layout."""
    array = draw(hnp.arrays(np.float32, shape, elements=st.floats(-1.5, 1.5, width=32)))
    return _relayout(array, draw(st.sampled_from(_LAYOUTS)))


def _valid_actions(shape: tuple[int, ...]) -> st.SearchStrategy[np.ndarray]:
    return hnp.arrays(np.float32, shape, elements=st.floats(-1.0, 1.0, width=32))


def _action_inputs(shape: tuple[int, ...]) -> st.SearchStrategy[Any]:
    nested = hnp.arrays(object, _shapes(shape), elements=_OBJECTS).map(lambda a: a.tolist())
    ragged = st.lists(st.one_of(_OBJECTS, st.lists(_OBJECTS, max_size=3)), max_size=5)
    junk = st.one_of(
        _OBJECTS,
        st.dictionaries(st.text(max_size=2), st.integers(), max_size=2),
        st.just(object()),
        st.sets(st.integers(0, 3), max_size=2),
    )
    return st.one_of(_arrays(shape), _arrays(shape), _plausible_arrays(shape), nested, ragged, junk)


# --- action oracle ----------------------------------------------------------------------------


@dataclasses.dataclass
class _Expect:
    """What a step with some input must do."""

    ok: bool
    action: np.ndarray | None = None  # when ok: the float32 action the twin applies
    problems: frozenset[str] = frozenset()  # when rejected: what the message may name
    nonfinite: frozenset[tuple[int, int]] = frozenset()  # (world, element) of NaN/inf entries
    may_reject: bool = False  # ok, but an ActionError is an acceptable answer too


def _positions(mask: np.ndarray) -> frozenset[tuple[int, int]]:
    """(world, element) indices of the true entries of a (d,) or (n, d) mask."""
    mask = np.atleast_2d(mask)
    return frozenset((int(i), int(j)) for i, j in zip(*np.nonzero(mask), strict=True))


def _is_huge_int(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and abs(value) > 1e308


def _lenient_expectation(action: Any, shape: tuple[int, ...]) -> _Expect:
    """For the envs: any real numbers (bool, int, float, or objects holding those) of the right
    shape are valid, finite values outside [-1, 1] are clipped; anything else is rejected.
    """
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            array = np.asarray(action)
        except (ValueError, TypeError):  # ragged nesting
            return _Expect(False, problems=frozenset({"dtype", "shape"}))
    problems: set[str] = set()
    huge_ints = False
    if array.dtype.kind == "O":
        items = array.ravel().tolist()
        if not all(isinstance(x, _REAL_SCALARS) for x in items):
            problems.add("dtype")
        huge_ints = any(_is_huge_int(x) for x in items)
    elif array.dtype.kind not in "biuf":
        problems.add("dtype")
    if array.shape != shape:
        problems.add("shape")

    # A plain float32 conversion: the shape NumPy sees, and the NaN that None and "nan" become.
    converted = None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with contextlib.suppress(TypeError, ValueError, OverflowError):
            converted = np.asarray(action, dtype=np.float32)
    if converted is not None and converted.shape != shape:
        problems.add("shape")

    nonfinite: frozenset[tuple[int, int]] = frozenset()
    if not problems:
        if array.dtype.kind == "f":
            real = array
        else:
            # Objects holding real numbers: huge ints stand in as ±2 (clipped to ±1 anyway).
            real = np.array(
                [(2.0 if x > 0 else -2.0) if _is_huge_int(x) else float(x) for x in array.flat],
                dtype=np.float64,
            ).reshape(array.shape)
        finite = np.isfinite(real)
        if not finite.all():
            problems.add("finite")
            nonfinite = _positions(~finite)
        else:
            clipped = np.clip(real, -1, 1).astype(np.float32)
            return _Expect(True, clipped, may_reject=huge_ints)
    elif converted is not None and not np.isfinite(converted).all():
        # None and "nan" become NaN: a message about NaN names a real problem.
        problems.add("finite")
        if converted.shape == shape:
            nonfinite = _positions(~np.isfinite(converted))
    return _Expect(False, problems=frozenset(problems), nonfinite=nonfinite)


def _strict_expectation(action: Any, shape: tuple[int, ...]) -> _Expect:
    """For the raw Batch: a native float32 ndarray of shape (N, act_dim), any layout, finite."""
    problems: set[str] = set()
    if not (isinstance(action, np.ndarray) and action.dtype == np.dtype(np.float32)):
        problems.add("dtype")
    if not isinstance(action, np.ndarray) or action.shape != shape:
        problems.add("shape")
    if problems:
        return _Expect(False, problems=frozenset(problems))
    finite = np.isfinite(action)
    if not finite.all():
        return _Expect(False, problems=frozenset({"finite"}), nonfinite=_positions(~finite))
    return _Expect(True, np.ascontiguousarray(np.clip(action, -1, 1)))


def _expectation(action: Any, shape: tuple[int, ...], strict: bool) -> _Expect:
    return _strict_expectation(action, shape) if strict else _lenient_expectation(action, shape)


_NONFINITE_MESSAGE = re.compile(r"world (\d+) element (\d+) is (NaN|-?inf)")


def _assert_action_error(error: BaseException | None, expect: _Expect, shape: tuple) -> None:
    """A rejection: an ActionError whose message names one of the input's problems."""
    assert isinstance(error, ActionError), f"expected ActionError, got {_describe(error)}"
    message = str(error)
    named = set()
    if "shape" in message and str(shape) in message:
        named.add("shape")
    if re.search(r"numeric|dtype|float32", message):
        named.add("dtype")
    found = _NONFINITE_MESSAGE.search(message)
    if found and "finite" in message:
        named.add("finite")
        if expect.nonfinite:
            world, element = int(found[1]), int(found[2])
            assert (world, element) in expect.nonfinite, (
                f"{message!r} names world {world} element {element}, not one of the "
                f"non-finite entries {sorted(expect.nonfinite)}"
            )
    assert named & expect.problems, (
        f"{message!r} names {sorted(named) or 'nothing'}, the input's problems are "
        f"{sorted(expect.problems)}"
    )


def _check_action(pair: _Pair, seed: int, prefix: list, action: Any, follow: np.ndarray) -> None:
    """Resets env and twin, steps both through ``prefix``, tries ``action`` on the env only, and
    checks the outcome against the oracle; then both must step ``follow`` alike."""
    pair.reset_both(seed)
    for valid in prefix:
        pair.step_both(valid)
    expect = _expectation(action, pair.shape, pair.strict)
    note(f"expectation: {expect}")
    event("valid" if expect.ok else f"invalid: {', '.join(sorted(expect.problems))}")
    before = pair.poses(pair.env)
    out, error = _attempt(lambda: pair.step(pair.env, action))
    note(f"outcome: {_describe(error)}")
    if expect.ok and not (expect.may_reject and isinstance(error, ActionError)):
        assert error is None, f"valid action {action!r} was rejected: {_describe(error)}"
        _assert_same(out, pair.step(pair.twin, expect.action), "step (clipped twin)")
        pair.check_outputs(out)
    else:
        assert error is not None, f"invalid action {action!r} was accepted"
        _assert_action_error(error, expect, pair.shape)
        np.testing.assert_array_equal(pair.poses(pair.env), before, "a world moved")
    pair.step_both(follow)


# --- 1. actions -------------------------------------------------------------------------------


@pytest.mark.parametrize("backend", ["single", "vector", "batch"])
@pytest.mark.parametrize("env_id", ENV_IDS)
@given(data=st.data())
def test_any_action_is_applied_clipped_or_rejected_with_action_error(
    env_id: str, backend: str, data: st.DataObject
) -> None:
    pair = _get_pair(backend, env_id)
    seed = data.draw(st.integers(0, 2**32 - 1), label="seed")
    prefix = data.draw(st.lists(_valid_actions(pair.shape), max_size=2), label="prefix")
    action = data.draw(_action_inputs(pair.shape), label="action")
    follow = data.draw(_valid_actions(pair.shape), label="follow-up action")
    with _watchdog():
        _check_action(pair, seed, prefix, action, follow)


# --- 2. a rejected action corrupts no world ---------------------------------------------------


@st.composite
def _nonfinite_cells(draw: st.DrawFn, shape: tuple[int, ...]) -> np.ndarray:
    """Valid float32 actions with NaN/±inf in one or a few cells (one world's row, say)."""
    array = draw(hnp.arrays(np.float32, shape, elements=st.floats(-1.5, 1.5, width=32)))
    cells = st.tuples(*(st.integers(0, side - 1) for side in shape))
    for cell in draw(st.lists(cells, min_size=1, max_size=3)):
        array[cell] = draw(st.sampled_from([np.nan, np.inf, -np.inf]))
    return _relayout(array, draw(st.sampled_from(_LAYOUTS)))


def _bad_actions(shape: tuple[int, ...], strict: bool) -> st.SearchStrategy[Any]:
    def rejected(action: Any) -> bool:
        expect = _expectation(action, shape, strict)
        return not expect.ok

    return st.one_of(_nonfinite_cells(shape), _action_inputs(shape)).filter(rejected)


@pytest.mark.parametrize("backend", ["vector", "batch"])
@pytest.mark.parametrize("env_id", ENV_IDS)
@given(data=st.data())
def test_rejected_action_leaves_every_world_untouched(
    env_id: str, backend: str, data: st.DataObject
) -> None:
    # Short episodes, so that worlds end (and are due for an autoreset) around the bad action.
    max_steps = data.draw(st.integers(1, 4), label="max_steps")
    pair = _get_pair(backend, env_id, max_steps)
    seed = data.draw(st.integers(0, 2**32 - 1), label="seed")
    prefix = data.draw(st.lists(_valid_actions(pair.shape), max_size=6), label="prefix")
    bad = data.draw(_bad_actions(pair.shape, pair.strict), label="bad action")
    follow = data.draw(st.lists(_valid_actions(pair.shape), min_size=1, max_size=3))
    with _watchdog():
        pair.reset_both(seed)
        for action in prefix:
            pair.step_both(action)
        poses = pair.poses(pair.env)
        readings = pair.env.sensor_readings() if backend != "single" else None
        _, error = _attempt(lambda: pair.step(pair.env, bad))
        _assert_action_error(error, _expectation(bad, pair.shape, pair.strict), pair.shape)
        np.testing.assert_array_equal(pair.poses(pair.env), poses, "a world moved", strict=True)
        _assert_same(pair.env.sensor_readings(), readings, "sensor readings")
        for action in follow:
            pair.step_both(action)


# --- 3. seeds ---------------------------------------------------------------------------------

_NUMPY_INTS = st.sampled_from(
    [np.int8, np.int16, np.int32, np.int64, np.uint8, np.uint16, np.uint32, np.uint64]
).flatmap(lambda t: hnp.from_dtype(np.dtype(t)).map(t))

_INT_SEEDS = st.one_of(
    st.integers(0, 2**32),
    st.integers(0, U64 - 1),
    st.integers(-(2**70), 2**70),
    st.sampled_from([0, 1, -1, 2**63 - 1, 2**63, U64 - 1, U64, U64 + 1, 10**30, -(2**63)]),
)

_SEEDS = st.one_of(
    st.none(),
    _INT_SEEDS,
    _INT_SEEDS,
    st.booleans(),
    _NUMPY_INTS,
    st.floats(),
    st.text(max_size=5),
    st.binary(max_size=4),
    st.complex_numbers(),
    st.lists(_INT_SEEDS, max_size=6),
    st.lists(st.one_of(st.none(), st.integers(0, 99), _NUMPY_INTS), min_size=4, max_size=4),
    st.lists(
        st.one_of(st.none(), _INT_SEEDS, st.floats(), st.text(max_size=2)), min_size=4, max_size=4
    ),
    st.tuples(st.integers(0, 9), st.integers(0, 9), st.integers(0, 9), st.integers(0, 9)),
    hnp.arrays(
        st.sampled_from([np.dtype(np.int64), np.dtype(np.uint64), np.dtype(np.float64)]),
        st.sampled_from([(4,), (3,), (2, 2), ()]),
    ),
    st.dictionaries(st.integers(0, 3), st.integers(0, 3), max_size=4),
    st.just(object()),
)


def _is_int(value: Any) -> bool:
    return isinstance(value, (int, np.integer))


def _index(value: Any) -> int | None:
    """``operator.index(value)`` (ints, NumPy ints, 0-d int arrays), or None."""
    try:
        return operator.index(value)
    except TypeError:
        return None


@dataclasses.dataclass
class _SeedExpect:
    ok: bool
    world_seeds: list[int | None] | None = None  # when ok: each world's seed (None: continue)
    errors: tuple[type[BaseException], ...] = (KheperaError,)
    words: tuple[str, ...] = ("seed",)  # a rejection's message names one of these
    may_reject: bool = False


# A seed that is not a non-negative Python int (below 2**64) is refused with our ConfigError,
# before Gymnasium's own check (``gymnasium.utils.seeding.np_random``, whose ``gymnasium.error``
# would not be a KheperaError), in the single env and the vector env alike (issue 33).
_SEED_ERRORS = (ConfigError,)


def _single_seed_expectation(seed: Any) -> _SeedExpect:
    if seed is None:
        return _SeedExpect(True, [None])
    if isinstance(seed, int):  # bool included, as in Gymnasium
        if seed < 0:
            return _SeedExpect(False, errors=_SEED_ERRORS)
        if seed >= U64:  # Gymnasium takes it; working or a KheperaError are both fine
            return _SeedExpect(True, [seed], may_reject=True)
        return _SeedExpect(True, [int(seed)])
    return _SeedExpect(False, errors=_SEED_ERRORS)


def _vector_seed_expectation(seed: Any, n: int) -> _SeedExpect:
    if seed is None:
        return _SeedExpect(True, [None] * n)
    if _is_int(seed):
        value = int(seed)
        if value < 0:
            return _SeedExpect(False, errors=_SEED_ERRORS)
        if value >= U64:
            return _SeedExpect(True, [None] * n, may_reject=True)
        # World i is seeded s + i; where that passes 2**64 it is unspecified, so not compared.
        return _SeedExpect(True, [value + i if value + i < U64 else None for i in range(n)])
    is_sequence = isinstance(seed, (list, tuple)) or (
        isinstance(seed, np.ndarray) and seed.ndim == 1
    )
    if not is_sequence:
        return _SeedExpect(False)
    seeds = list(seed)
    if len(seeds) != n:
        return _SeedExpect(False, words=(f"{n} seeds",))
    if all(s is None or (_is_int(s) and 0 <= int(s) < U64) for s in seeds):
        return _SeedExpect(True, [None if s is None else int(s) for s in seeds])
    return _SeedExpect(False)


def _check_seed_rejection(error: BaseException | None, expect: _SeedExpect) -> None:
    assert isinstance(error, expect.errors), (
        f"expected {[c.__name__ for c in expect.errors]}, got {_describe(error)}"
    )
    assert any(word in str(error) for word in expect.words), (str(error), expect.words)


def _check_seed(
    pair: _Pair,
    seed: Any,
    expect: _SeedExpect,
    check_worlds: Callable[[np.ndarray], None] | None = None,
) -> None:
    """Resets ``pair.env`` with ``seed``: a rejection as ``expect`` says, or observations that a
    second reset and the twin reproduce (and ``check_worlds`` accepts); then both step alike."""
    with _watchdog():
        obs, error = _attempt(lambda: pair.reset(pair.env, seed))
        note(f"expectation {expect}, outcome {_describe(error)}")
        if not expect.ok or (expect.may_reject and isinstance(error, KheperaError)):
            _check_seed_rejection(error, expect)
        else:
            assert error is None, f"seed {seed!r} was rejected: {_describe(error)}"
            _assert_in_bounds(obs, pair.low, pair.high)
            if None not in expect.world_seeds:
                _assert_same(pair.reset(pair.env, seed), obs, "second reset, same seed")
                _assert_same(pair.reset(pair.twin, seed), obs, "twin reset, same seed")
                if check_worlds is not None:
                    check_worlds(obs)
                pair.step_both(np.zeros(pair.shape, np.float32))
        pair.reset_both(0)  # usable whatever happened


@pytest.mark.parametrize("env_id", ENV_IDS)
@given(seed=_SEEDS)
def test_single_env_seed_is_deterministic_or_rejected(env_id: str, seed: Any) -> None:
    _check_seed(_get_pair("single", env_id), seed, _single_seed_expectation(seed))


@pytest.mark.parametrize("env_id", ENV_IDS)
@given(seed=_SEEDS)
def test_vector_env_seed_is_deterministic_or_rejected(env_id: str, seed: Any) -> None:
    single = _single_core_env(env_id)
    expect = _vector_seed_expectation(seed, N_VECTOR)

    def each_world_is_a_single_env(obs: np.ndarray) -> None:
        for world, world_seed in enumerate(expect.world_seeds):
            _assert_same(single.reset(world_seed), obs[world : world + 1], f"world {world}")

    _check_seed(_get_pair("vector", env_id), seed, expect, each_world_is_a_single_env)


@functools.cache
def _single_core_env(env_id: str) -> _core.Batch:
    return _core.Batch(TASKS[env_id], 1, num_threads=1)


#: The raw core's int arguments are converted by pyo3, which raises TypeError (not an int) or
#: OverflowError (does not fit a u64/usize) before our code runs; tests/test_errors.py accepts
#: these for ``_core.Batch`` too. The Python envs are where user-facing checks belong.
_CORE_ARGUMENT_ERRORS = (KheperaError, TypeError, OverflowError)


@pytest.mark.parametrize("env_id", ENV_IDS)
@given(seed=_SEEDS, index=st.one_of(st.integers(-2, N_BATCH + 1), _SEEDS))
def test_batch_seed_and_world_index_are_checked(env_id: str, seed: Any, index: Any) -> None:
    pair = _get_pair("batch", env_id)
    single = _single_core_env(env_id)
    # pyo3 takes anything with __index__ (NumPy ints, 0-d int arrays) as an int.
    seed_index, world = _index(seed), _index(index)
    valid_seed = seed is None or (seed_index is not None and 0 <= seed_index < U64)
    valid_index = world is not None and 0 <= world < N_BATCH
    with _watchdog():
        obs, error = _attempt(lambda: pair.env.reset(seed))
        if not valid_seed:
            assert isinstance(error, _CORE_ARGUMENT_ERRORS), _describe(error)
        else:
            assert error is None, _describe(error)
            _assert_in_bounds(obs, pair.low, pair.high)
            if seed is not None:
                _assert_same(pair.env.reset(seed), obs, "second reset")
        row, error = _attempt(lambda: pair.env.reset_world(index, seed))
        if not (valid_seed and valid_index):
            assert isinstance(error, _CORE_ARGUMENT_ERRORS), _describe(error)
            if valid_seed and world is not None and 0 <= world < U64:
                assert isinstance(error, KheperaError), _describe(error)
        else:
            assert error is None, _describe(error)
            if seed is not None:  # reset_world seeds world i with the seed itself
                _assert_same(row[None], single.reset(seed), "reset_world vs a 1-world batch")
        # Whatever happened, the batch still steps in lockstep with its twin from a reset.
        pair.reset_both(7)
        pair.step_both(np.zeros(pair.shape, np.float32))


# --- 4. configs -------------------------------------------------------------------------------


@functools.cache
def _schema(task: str) -> dict[str, dict[str, Any]]:
    """The task's scenario, section -> key -> default, from its built-in file."""
    return tomllib.loads(_core.default_config(task))


def _dotted_keys(task: str) -> set[str]:
    return {f"{section}.{key}" for section, table in _schema(task).items() for key in table}


def _unambiguous_leaves(task: str) -> set[str]:
    schema = _schema(task)
    counts: dict[str, int] = {}
    for table in schema.values():
        for key in table:
            counts[key] = counts.get(key, 0) + 1
    return {key for key, count in counts.items() if count == 1 and key not in schema}


#: Keyword arguments that gym.make or the env constructors take themselves.
_RESERVED = {
    "id",
    "max_episode_steps",
    "disable_env_checker",
    "render_mode",
    "config",
    "action_type",
    "frame_size",
}
_CHOICES = {
    "placement": ["between", "anywhere", "nowhere"],
    "shape": ["cross", "line", "wedge", "circle", "custom", "square"],
    "leader": ["scripted", "agent", "human"],
}
_RANGE_PARAMS = {
    "axle_length",
    "max_wheel_speed",
    "wheel_accel_limit",
    "mass",
    "ir_floor_value",
    "ir_noise_sigma",
    "us_noise_sigma",
}
_SPECIAL_NUMBERS = st.sampled_from(
    [
        *(0.0, -0.0, -1.0, 5e-324, 1e-45, 1e-30, 1e-6, 1e6, 1e19, 1e20, 1e30, 3.5e38, 1e300),
        *(math.inf, -math.inf, math.nan, 0, -1, 1, 64, 65, 2**31, 2**32, 2**63, 2**64),
    ]
)
_WEIRD_NUMBERS = st.one_of(
    _SPECIAL_NUMBERS, st.floats(), st.integers(-3, 100), st.integers(-(2**70), 2**70)
)
_GARBAGE = st.one_of(
    st.none(),
    st.text(max_size=6),
    st.binary(max_size=3),
    st.lists(st.integers(-2, 2), max_size=3),
    st.lists(st.text(max_size=2), max_size=2),
    st.dictionaries(st.text(max_size=4), st.integers(-1, 1), max_size=2),
    st.dictionaries(st.integers(0, 2), st.integers(0, 2), min_size=1, max_size=1),
    st.tuples(st.floats(), st.floats()),
    st.builds(np.float32, st.floats(width=32)),
    st.builds(np.int64, st.integers(-(2**63), 2**63 - 1)),
    hnp.arrays(np.float64, st.integers(0, 3)),
    st.complex_numbers(),
    st.just(object()),
)


def _scaled(default: float, low: float = 0.5, high: float = 1.5) -> st.SearchStrategy[float]:
    """The default times a factor in [low, high] (about 1 in 3 such values fit a scenario)."""
    if not math.isfinite(default) or default == 0:
        return st.one_of(st.floats(0.01, 2.0), st.just(default))
    return st.floats(low, high).map(lambda f: default * f)


def _edgy(default: float) -> st.SearchStrategy[float]:
    """Around a default but likely impossible: 0 to 4 times it, or small numbers of any sign."""
    return st.one_of(_scaled(default, 0.0, 4.0), st.floats(-0.5, 2.0), st.just(-default))


def _points(size: int, span: float = 0.8) -> st.SearchStrategy[list[float]]:
    return st.lists(st.floats(-span, span), min_size=size, max_size=size)


def _ranges(default: float) -> st.SearchStrategy[list[float]]:
    """[low, high] ranges around a default: mostly ordered, sometimes reversed or mis-sized."""
    ordered = st.lists(_scaled(default), min_size=2, max_size=2).map(sorted)
    return st.one_of(
        ordered, ordered, ordered.map(lambda r: r[::-1]), st.lists(_edgy(default), max_size=3)
    )


_OBSTACLES = st.one_of(
    st.fixed_dictionaries(
        {"kind": st.just("circle"), "center": _points(2), "radius": st.floats(0.02, 0.2)}
    ),
    st.fixed_dictionaries(
        {
            "kind": st.just("box"),
            "center": _points(2),
            "half_extents": st.lists(st.floats(0.02, 0.2), min_size=2, max_size=2),
        },
        optional={"angle": st.floats(-4.0, 4.0) | _SPECIAL_NUMBERS},
    ),
    st.fixed_dictionaries({"kind": st.just("segment"), "a": _points(2), "b": _points(2)}),
    st.fixed_dictionaries(
        {"kind": st.just("circle"), "center": _points(2, 2.0), "radius": st.floats(0.0, 1.0)}
    ),
    st.dictionaries(
        st.sampled_from(["kind", "center", "radius", "half_extents", "angle", "a", "b", "color"]),
        st.one_of(
            st.sampled_from(["circle", "box", "segment", "blob"]), _points(2), _WEIRD_NUMBERS
        ),
        max_size=4,
    ),
)


def _plausible(key: str, default: Any) -> st.SearchStrategy[Any]:
    """Values of the right type for scenario key ``key``, near its default: many work."""
    if key in _CHOICES:
        return st.sampled_from(_CHOICES[key])
    if isinstance(default, bool):
        return st.booleans()
    if isinstance(default, int):
        return st.integers(default // 2, max(4, 2 * default))
    if isinstance(default, float):
        if key in _RANGE_PARAMS:
            return st.one_of(_scaled(default), _ranges(default))
        return _scaled(default)
    if key in ("circle_radius", "box_half_extent", "segment_length"):
        return _ranges(default[1])
    if key == "kinds":
        return st.lists(st.sampled_from(["circle", "box", "segment", "triangle"]), max_size=4)
    if key == "fixed":
        return st.lists(_OBSTACLES, max_size=5)
    if key in ("start", "goal"):
        size = 3 if key == "start" else 2
        return st.one_of(st.just([]), _points(size), _points(size, 3.0), _points(size + 1))
    if key == "us_enabled":
        return st.one_of(st.lists(st.booleans(), min_size=5, max_size=5), st.lists(st.booleans()))
    if key == "offsets":
        pair = st.tuples(st.floats(0.0, 1.5), st.floats(-7.0, 7.0)).map(list)
        return st.lists(pair, max_size=6)
    return st.nothing()


def _values(key: str, default: Any) -> st.SearchStrategy[Any]:
    """Plausible values (4 in 7), edgy numbers, extreme numbers, values of the wrong type."""
    plausible = _plausible(key, default)
    edgy = _edgy(default) if isinstance(default, float) else _plausible(key, default)
    return st.one_of(plausible, plausible, plausible, plausible, edgy, _WEIRD_NUMBERS, _GARBAGE)


_IDENTIFIERS = st.text(
    alphabet=st.sampled_from("abcdefghijklmnopqrstuvwxyz_.0123456789 -"), max_size=12
)


@st.composite
def _overrides(draw: st.DrawFn, task: str, wild: bool = True) -> dict[str, Any]:
    """Keyword overrides: 1 to 3 keys, as leaf names, dotted names or section tables, and with
    ``wild`` unknown keys and values of any kind too (else values of the right type)."""
    schema = _schema(task)
    leaves = _unambiguous_leaves(task)
    known = _dotted_keys(task) | set(schema) | leaves
    overrides: dict[str, Any] = {}
    for _ in range(draw(st.integers(1, 3))):
        section = draw(st.sampled_from(sorted(schema)))
        key = draw(st.sampled_from(sorted(schema[section])))
        default = schema[section][key]
        value = draw(_values(key, default) if wild else _plausible(key, default))
        forms = ["leaf", "leaf", "leaf", "dotted", "section", "section"] + ["odd"] * wild
        form = draw(st.sampled_from(forms))
        if form == "leaf" and key in leaves:
            overrides[key] = value
        elif form == "section":
            table = overrides.get(section)
            overrides[section] = {**(table if isinstance(table, dict) else {}), key: value}
        elif form == "odd":
            name = draw(_IDENTIFIERS.filter(lambda s: s not in known and s not in _RESERVED))
            odd = draw(
                st.sampled_from(
                    [
                        (name, value),  # unknown key
                        (f"{section}.{name}", value),  # unknown key of a known section
                        (f"{name}.{key}", value),  # unknown section
                        (f"{section}.{key}.{name}", value),  # too deep
                        (section, value),  # a value where a table belongs
                        (section, {name: value}),  # unknown key in a section table
                    ]
                )
            )
            if odd[0] not in _RESERVED:
                overrides[odd[0]] = odd[1]
        else:
            overrides[f"{section}.{key}"] = value
    return overrides


#: Scenarios that cannot work, with the key the ConfigError must name.
_IMPOSSIBLE = [
    ({"count": 64, "circle_radius": [0.3, 0.4]}, "obstacles.count"),
    ({"count": 64, "min_gap": 0.5}, "obstacles.count"),
    ({"count": 65}, "obstacles.count"),
    ({"count": 5, "min_gap": 0.1}, "obstacles.min_gap"),
    ({"count": 3, "kinds": []}, "obstacles.kinds"),
    ({"fixed": [{"kind": "circle", "center": [0.0, 0.0], "radius": 5.0}]}, "obstacles.fixed[0]"),
    ({"fixed": [{"kind": "box", "center": [1.4, 1.4], "half_extents": [0.3, 0.3]}]}, "fixed[0]"),
    ({"fixed": [{"kind": "segment", "a": [0.0, 0.0], "b": [0.0, 0.0]}]}, "obstacles.fixed[0]"),
    ({"radius": 1.5}, "radius"),
    ({"width": 0.1}, "arena.width"),
    ({"width": 0.5, "height": 0.5, "min_goal_distance": 3.0}, "min_goal_distance"),
    ({"start": [5.0, 5.0, 0.0]}, "spawn.start"),
    ({"goal": [5.0, 5.0]}, "spawn.goal"),
    ({"min_wheel_speed": 1.0}, "robot.min_wheel_speed"),
    ({"mass": [2.0, 1.0]}, "robot.mass"),
    ({"ir_range": 0.1}, "sensors.ir_range"),
    ({"us_min_range": 3.0}, "sensors.us_min_range"),
    ({"substeps": 65}, "physics.substeps"),
    ({"dt": 2.0}, "physics.dt"),
]
_IMPOSSIBLE_FORMATION = [
    ({"n_followers": 17}, "formation.n_followers"),
    ({"n_followers": 0}, "formation.n_followers"),
    ({"spacing": 0.1}, "formation.spacing"),
    ({"spacing": 5.0}, "spawn"),
    ({"shape": "custom", "offsets": []}, "formation.offsets"),
    ({"shape": "custom", "offsets": [[0.5, 0.0], [0.5, 0.0]]}, "formation.offsets"),
]


def _impossible(task: str) -> list[tuple[dict[str, Any], str]]:
    """The impossible overrides for TASK. The cases are written for the shared sections; a bare
    key that TASK also has in its own section (LineFollow's `width`: the arena's and the
    line's) is ambiguous, an error of its own, so there it is written with its shared section."""
    cases = _IMPOSSIBLE + (_IMPOSSIBLE_FORMATION if task == "formation" else [])
    schema = _schema(task)

    def qualified(key: str) -> str:
        sections = [name for name, table in schema.items() if key in table]
        shared = [name for name in sections if name != task]
        return f"{shared[0]}.{key}" if len(sections) > 1 and len(shared) == 1 else key

    return [
        ({qualified(k): v for k, v in overrides.items()}, expected) for overrides, expected in cases
    ]


def _assert_config_error_names_a_key(
    error: BaseException | None, origin: str, task: str, given_keys: list[str]
) -> None:
    """A ConfigError "ORIGIN: KEY: problem" whose KEY is a scenario key or one the user gave."""
    assert isinstance(error, ConfigError), f"expected ConfigError, got {_describe(error)}"
    message = str(error)
    assert message.startswith(f"{origin}: "), f"{message!r} does not start with {origin!r}"
    rest = message[len(origin) + 2 :]
    candidates = _dotted_keys(task) | set(_schema(task)) | {"spawn"}
    for key in given_keys:
        parts = key.split(".")
        candidates |= {key, parts[-1]} | {".".join(parts[: i + 1]) for i in range(len(parts))}
    assert any(
        rest.startswith(f"{key}: ") or rest.startswith(f"{key}[") or rest.startswith(f"{key}.")
        for key in candidates
    ), f"{message!r} names no scenario key nor any of {given_keys}"


def _leaves(value: Any) -> Iterator[Any]:
    if isinstance(value, dict):
        for item in value.values():
            yield from _leaves(item)
    elif isinstance(value, (list, tuple)):
        for item in value:
            yield from _leaves(item)
    else:
        yield value


def _check_override_message(error: BaseException | None, overrides: dict[str, Any]) -> None:
    """ "integer out of range" must be about an int that does not fit 64 bits."""
    assert "integer out of range" not in str(error) or any(
        _is_int(v) and not -(2**63) <= int(v) < 2**63 for v in _leaves(overrides)
    ), str(error)


def _check_built_env(env: gym.Env, seed: int, data: st.DataObject) -> None:
    """A scenario that built must reset and step with finite observations inside the space."""
    space = env.observation_space
    obs, error = _attempt(lambda: env.reset(seed=seed)[0])
    assert error is None, f"reset failed: {_describe(error)}"
    _assert_in_bounds(obs, space.low, space.high)
    for step in range(3):
        action = data.draw(_valid_actions(env.action_space.shape), label=f"action {step}")
        out, error = _attempt(lambda a=action: env.step(a))
        assert error is None, f"step failed: {_describe(error)}"
        obs, reward, terminated, truncated, _ = out
        _assert_in_bounds(obs, space.low, space.high)
        assert math.isfinite(reward), f"non-finite reward {reward}"
        if terminated or truncated:
            break


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_every_impossible_scenario_is_refused_naming_its_key(env_id: str) -> None:
    """Each impossible case, on every task, not only those the random draw happens to pick:
    a ConfigError that names the key at fault (a LineFollow `width` was ambiguous, and only a
    CI run's draw showed it)."""
    task = TASKS[env_id]
    for overrides, key in _impossible(task):
        env, error = _attempt(lambda o=overrides: gym.make(env_id, **o))
        assert env is None, f"impossible {overrides} was accepted on {env_id}"
        _assert_config_error_names_a_key(error, "<override>", task, list(overrides))
        assert key in str(error), (overrides, str(error), key)


@pytest.mark.parametrize("env_id", ENV_IDS)
@given(data=st.data())
def test_config_overrides_build_a_working_env_or_raise_config_error(
    env_id: str, data: st.DataObject
) -> None:
    task = TASKS[env_id]
    overrides = data.draw(
        st.one_of(
            _overrides(task, wild=False),
            _overrides(task),
            _overrides(task),
            st.sampled_from(_impossible(task)).map(lambda c: c[0]),
        ),
        label="overrides",
    )
    seed = data.draw(st.integers(0, 2**32 - 1), label="seed")
    with _watchdog():
        env, error = _attempt(lambda: gym.make(env_id, **overrides))
        if error is not None:
            event("ConfigError")
            _assert_config_error_names_a_key(error, "<override>", task, list(overrides))
            _check_override_message(error, overrides)
            for impossible, key in _impossible(task):
                if repr(overrides) == repr(impossible):
                    assert key in str(error), (str(error), key)
            return
        event("built")
        for impossible, _ in _impossible(task):
            assert repr(overrides) != repr(impossible), f"impossible {overrides} was accepted"
        _check_built_env(env, seed, data)
        env.close()


@pytest.mark.parametrize("task", ["multinav", "platoon"])
@given(data=st.data())
def test_multi_robot_batch_overrides_build_a_working_batch_or_raise_config_error(
    task: str, data: st.DataObject
) -> None:
    """The PettingZoo-only tasks through the raw Batch: several robots, own goals (multinav) or
    time-shifted references (platoon)."""
    overrides = data.draw(
        st.one_of(_overrides(task, wild=False), _overrides(task)), label="overrides"
    )
    with _watchdog():
        batch, error = _attempt(lambda: _core.Batch(task, 2, overrides=overrides))
        if error is not None:
            event("ConfigError")
            _assert_config_error_names_a_key(error, "<override>", task, list(overrides))
            _check_override_message(error, overrides)
            return
        event("built")
        low, high = batch.obs_bounds()
        obs, error = _attempt(lambda: batch.reset(data.draw(st.integers(0, 2**32 - 1))))
        assert error is None, _describe(error)
        _assert_in_bounds(obs, low, high)
        for _ in range(2):
            action = data.draw(_valid_actions((2, batch.act_dim)))
            out, error = _attempt(lambda a=action: batch.step(a))
            assert error is None, _describe(error)
            _assert_in_bounds(out[0], low, high)
            assert np.isfinite(out[1]).all(), out[1]


# --- scenario files ---------------------------------------------------------------------------


def _toml_key(key: str) -> str:
    return key if re.fullmatch(r"[A-Za-z0-9_-]+", key) else json.dumps(key)


def _toml_value(value: Any) -> str:
    """TOML for Python values; anything TOML has no syntax for becomes a string."""
    if isinstance(value, (bool, np.bool_)):
        return "true" if value else "false"
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if isinstance(value, (float, np.floating)):
        value = float(value)
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return repr(value)
    if isinstance(value, (list, tuple, np.ndarray)):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        items = (f"{_toml_key(str(k))} = {_toml_value(v)}" for k, v in value.items())
        return "{" + ", ".join(items) + "}"
    if isinstance(value, bytes):
        value = value.decode("latin-1")
    return json.dumps(value if isinstance(value, str) else repr(value))


def _toml_document(table: dict[str, Any]) -> str:
    lines = [f"{_toml_key(k)} = {_toml_value(v)}" for k, v in table.items() if not _is_table(v)]
    for name, body in table.items():
        if _is_table(body):
            lines.append(f"[{_toml_key(name)}]")
            lines += [f"{_toml_key(k)} = {_toml_value(v)}" for k, v in body.items()]
    return "\n".join(lines) + "\n"


def _is_table(value: Any) -> bool:
    return isinstance(value, dict) and all(isinstance(k, str) for k in value)


@st.composite
def _scenario_files(draw: st.DrawFn, task: str) -> str | bytes:
    """TOML text: tables of known and unknown keys with random values, sometimes mangled."""
    schema = _schema(task)
    table: dict[str, Any] = {}
    for _ in range(draw(st.integers(0, 4))):
        section = draw(st.sampled_from(sorted(schema)) | _IDENTIFIERS)
        keys = sorted(schema.get(section, {})) or ["x"]
        key = draw(st.sampled_from(keys) | _IDENTIFIERS)
        value = draw(_values(key, schema.get(section, {}).get(key, 0.0)))
        if value is None or not _toml_able(value):
            continue
        if not isinstance(table.get(section), dict):
            table[section] = {}
        table[section][key] = value
    text = _toml_document(table)
    mangle = draw(
        st.sampled_from(
            ["none"] * 6 + ["truncate", "insert", "junk", "duplicate", "fixed", "text", "bytes"]
        )
    )
    if mangle == "truncate":
        text = text[: draw(st.integers(0, len(text)))]
    elif mangle == "insert":
        at = draw(st.integers(0, len(text)))
        inserted = draw(st.text(st.sampled_from('[]="{},.\n#\\x1 '), max_size=4))
        text = text[:at] + inserted + text[at:]
    elif mangle == "junk":
        text += draw(st.text(max_size=20))
    elif mangle == "duplicate" and table:
        text += text
    elif mangle == "fixed":
        for obstacle in draw(st.lists(_OBSTACLES, max_size=3)):
            text += "[[obstacles.fixed]]\n" + "".join(
                f"{_toml_key(k)} = {_toml_value(v)}\n" for k, v in obstacle.items()
            )
    elif mangle == "text":
        return draw(st.text(max_size=60))
    elif mangle == "bytes":
        return draw(st.binary(max_size=40))
    return text


def _toml_able(value: Any) -> bool:
    return isinstance(
        value, (bool, int, float, str, bytes, list, tuple, dict, np.generic, np.ndarray)
    ) and not isinstance(value, (complex, np.complexfloating))


@pytest.fixture(scope="module")
def scenario_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("fuzz_scenarios")


@pytest.mark.parametrize("env_id", ENV_IDS)
@given(data=st.data())
def test_scenario_file_builds_a_working_env_or_raises_config_error(
    env_id: str, scenario_dir: Path, data: st.DataObject
) -> None:
    task = TASKS[env_id]
    contents = data.draw(_scenario_files(task), label="scenario file")
    path = scenario_dir / "fuzzed.toml"
    if isinstance(contents, bytes):
        path.write_bytes(contents)
    else:
        path.write_text(contents, encoding="utf-8", errors="surrogatepass")
    seed = data.draw(st.integers(0, 2**32 - 1), label="seed")
    with _watchdog():
        env, error = _attempt(lambda: gym.make(env_id, config=str(path)))
        if error is not None:
            event("ConfigError")
            assert isinstance(error, ConfigError), _describe(error)
            message = str(error)
            assert message.startswith(f"{path}: "), f"{message!r} does not name the file first"
            rest = message[len(str(path)) + 2 :]
            line = re.match(r"line (\d+): ", rest)
            # A line number past the end of the file would count lines of some internal text.
            assert not (
                line and isinstance(contents, str) and int(line[1]) > contents.count("\n") + 1
            ), message
            if not (line or re.match(r"(<syntax>|cannot read scenario file): ", rest)):
                # Otherwise it names a key: one of the scenario's or a word of the file.
                text = (
                    contents.decode("utf-8", "replace") if isinstance(contents, bytes) else contents
                )
                words = re.findall(r'[A-Za-z0-9_-]+|"[^"\n]*"', text)
                words += [w.strip('"') for w in words]  # as written and unquoted
                if re.search(r"^\s*=", text, re.MULTILINE):
                    words.append("")  # "= 1": the key named is the empty one
                _assert_config_error_names_a_key(error, str(path), task, words)
            return
        event("built")
        _check_built_env(env, seed, data)
        env.close()


@pytest.mark.parametrize("env_id", ENV_IDS)
@given(
    config=st.one_of(
        st.sampled_from(
            [
                *_core.builtin_configs(),
                *("", ".", "..", "NAV", "nav.toml", "README.md", "configs"),
                *("\x00.toml", "nav\x00", "x.toml\x00"),
            ]
        ),
        st.text(st.characters(exclude_characters="/\\" + os.sep), max_size=12),
        st.integers(),
        st.binary(max_size=4),
        st.lists(st.text(max_size=3), max_size=2),
    )
)
def test_config_argument_is_a_known_scenario_or_raises_config_error(
    env_id: str, config: Any
) -> None:
    with _watchdog():
        env, error = _attempt(lambda: gym.make(env_id, config=config))
        if error is not None:
            assert isinstance(error, ConfigError), _describe(error)
            if isinstance(config, str) and config:
                assert config in str(error) or repr(config) in str(error), str(error)
            return
        assert isinstance(config, str) and config in _core.builtin_configs(), config
        obs, _ = env.reset(seed=0)
        _assert_in_bounds(obs, env.observation_space.low, env.observation_space.high)
        env.close()


# --- regression tests: a minimal repro of each bug this suite found (all fixed) -------------


def _nav_pair() -> tuple[gym.Env, gym.Env]:
    env, twin = NavEnv(), NavEnv()
    env.reset(seed=0)
    twin.reset(seed=0)
    return env, twin


def test_bug_finite_float64_action_beyond_float32_range_is_clipped() -> None:
    env, twin = _nav_pair()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        observation = env.step(np.array([1e300, -1e300]))[0]  # RuntimeWarning, or "is inf"
    np.testing.assert_array_equal(observation, twin.step(np.array([1.0, -1.0], np.float32))[0])


def test_bug_huge_python_int_in_action_is_clipped_or_action_error() -> None:
    env, twin = _nav_pair()
    try:
        observation = env.step([10**400, 0])[0]  # OverflowError: int too large to convert
    except ActionError:
        return
    np.testing.assert_array_equal(observation, twin.step(np.array([1.0, 0.0], np.float32))[0])


def test_bug_complex_action_raises_action_error() -> None:
    env, _ = _nav_pair()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # was: ComplexWarning, then the real part is used
        with pytest.raises(ActionError, match=r"dtype|numeric|complex"):
            env.step(np.array([0.5 + 0.5j, 0.5]))


@pytest.mark.parametrize(
    "action",
    [
        np.array(["1", "0.5"]),
        ["1", "0.5"],
        [b"1", b"0.5"],
        np.zeros(2, "datetime64[s]"),
        np.zeros(2, "timedelta64[s]"),
    ],
    ids=["str-array", "str-list", "bytes-list", "datetime64", "timedelta64"],
)
def test_bug_non_numeric_action_raises_action_error(action: Any) -> None:
    env, _ = _nav_pair()
    with pytest.raises(ActionError):
        env.step(action)  # was: accepted as numbers


@pytest.mark.parametrize("vector", [False, True], ids=["single", "vector"])
def test_bug_seed_beyond_u64_works_or_raises_khepera_error(vector: bool) -> None:
    env = gym.make_vec(LATEST["nav"], num_envs=2) if vector else gym.make(LATEST["nav"])
    with contextlib.suppress(KheperaError):
        env.reset(seed=2**64)  # was: OverflowError: int too big to convert
    env.close()


@pytest.mark.parametrize(
    "seed",
    [1.5, "abcd", "a", [-1, 0, 0, 0], [2**64, 0, 0, 0], [1.5, 0, 0, 0], ["5", 0, 0, 0]],
    ids=["float", "str4", "str1", "negative", "big", "float-list", "str-list"],
)
def test_bug_vector_reset_with_a_bad_seed_raises_khepera_error_naming_seed(seed: Any) -> None:
    # Was: TypeError ('float' object is not iterable), ValueError (int('a')), a ConfigError
    # about "a sequence of 1", OverflowError, or floats/strings silently truncated/parsed.
    envs = gym.make_vec(LATEST["nav"], num_envs=4)
    with pytest.raises(KheperaError, match="seed") as raised:
        envs.reset(seed=seed)
    assert "sequence of 1" not in str(raised.value)
    envs.close()


def test_bug_huge_arena_is_rejected_or_gives_finite_observations() -> None:
    try:
        env = NavEnv(width=1e20, height=1e20)
    except ConfigError:
        return
    observation, _ = env.reset(seed=0)  # was: goal_distance inf
    assert np.isfinite(observation).all(), observation
    _, reward, *_ = env.step(np.zeros(2, np.float32))
    assert math.isfinite(reward), reward  # was: NaN


def test_bug_non_str_key_in_override_table_raises_config_error() -> None:
    with pytest.raises(ConfigError):
        gym.make(LATEST["nav"], robot={1: 0.1})  # was: TypeError: config keys must be str


@pytest.mark.parametrize(
    ("overrides", "key"),
    [({"mass": {"a": 1}}, "robot.mass"), ({"robot.radius.x": 3}, "robot.radius")],
)
def test_bug_table_where_a_value_belongs_names_the_key(overrides: dict, key: str) -> None:
    with pytest.raises(ConfigError, match=re.escape(key)):  # was: "<override>: line 33: ..."
        NavEnv(**overrides)


@pytest.mark.parametrize("value", [np.array([0.5, 0.6]), np.array(0.5)], ids=["1-d", "0-d"])
def test_bug_ndarray_override_works_or_names_its_type(value: np.ndarray) -> None:
    try:
        NavEnv(mass=value)  # was: ConfigError "<override>: mass: integer out of range"
    except ConfigError as error:
        assert "integer out of range" not in str(error), str(error)
