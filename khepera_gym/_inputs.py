"""Checks and conversions of what users pass to ``step`` and ``reset``, shared by every env.

Actions: anything NumPy reads as real numbers (floats of any width, ints, bools, or objects
holding those) of the right shape becomes a C-contiguous float32 array; finite values beyond
float32's range are clipped to it (the core clips every action to [-1, 1] anyway), so a huge value
is never turned into inf. Everything else (strings, bytes, complex numbers, dates, None, ragged
lists) raises :class:`~khepera_gym.errors.ActionError` naming the dtype or the shape; NaN/inf are
left for the core, which names the world and element.

Seeds: a seed is a non-negative int below 2**64 (the core's seeds are u64).

Reset masks (``reset(options={"reset_mask": mask})`` of a vector env): a NumPy bool array of one
value per world with at least one True, as Gymnasium's own vector envs require. Reset options:
None or a mapping.

Counts and indices (``num_envs``, ``num_threads``, ``render_worlds``, ``frame_size``,
``scene(i)``): a Python or NumPy int (not a bool, not a float with an integral value) within
the argument's range. Everything else raises :class:`~khepera_gym.errors.ConfigError` naming the
argument, never a ``TypeError`` or ``OverflowError``.
"""

from __future__ import annotations

import numbers
from collections.abc import Mapping
from typing import Any

import numpy as np
import numpy.typing as npt

from khepera_gym.errors import ActionError, ConfigError

_F32_MAX = float(np.finfo(np.float32).max)
#: Seeds are u64 in the core.
SEED_LIMIT = 2**64


def _real_scalar(value: Any) -> bool:
    return isinstance(value, (numbers.Real, np.bool_))


def _clip_to_f32(value: Any) -> float:
    """An object array's element as a float within float32's range (huge ints included)."""
    if isinstance(value, numbers.Integral):
        return float(max(-_F32_MAX, min(_F32_MAX, int(value))))
    number = float(value)
    return number if not np.isfinite(number) else max(-_F32_MAX, min(_F32_MAX, number))


def _within_float32(array: npt.NDArray[np.floating]) -> bool:
    """Whether every value is finite and within float32's range (False for NaN/inf too)."""
    if array.size <= 64:  # a Python loop beats NumPy's reductions on small arrays
        return all(-_F32_MAX <= value <= _F32_MAX for value in array.ravel().tolist())
    return bool(np.abs(array).max() <= _F32_MAX)


def _to_float32(action: Any, shape: tuple[int, ...], what: str) -> npt.NDArray[np.float32]:
    try:
        array = np.asarray(action)
    except (TypeError, ValueError, OverflowError) as error:  # ragged nesting, odd objects
        raise ActionError(
            f"{what} must be real numbers (a numeric dtype) of shape {shape}, "
            f"got {type(action).__name__}: {error}"
        ) from None
    kind = array.dtype.kind
    if kind == "O":
        items = array.ravel().tolist()
        bad = [item for item in items if not _real_scalar(item)]
        if bad:
            raise ActionError(
                f"{what} must be real numbers (a numeric dtype) of shape {shape}, "
                f"got an element of type {type(bad[0]).__name__}: {bad[0]!r}"
            )
        values = np.array([_clip_to_f32(item) for item in items], np.float64)
        return values.reshape(array.shape).astype(np.float32)
    if kind not in "biuf":
        raise ActionError(
            f"{what} must be real numbers (a numeric dtype) of shape {shape}, "
            f"got dtype {array.dtype}"
        )
    if kind == "f" and array.dtype.itemsize > 4 and not _within_float32(array):
        # Finite float64/longdouble values beyond float32's range would become inf (NaN and inf
        # stay as they are, for the core to name).
        array = np.where(np.isfinite(array), np.clip(array, -_F32_MAX, _F32_MAX), array)
    return array.astype(np.float32)


def as_action_array(action: Any, shape: tuple[int, ...], what: str) -> npt.NDArray[np.float32]:
    """``action`` as a C-contiguous float32 array of ``shape``.

    Raises:
        ActionError: ``action`` is not real numbers, or not of ``shape``.
    """
    if isinstance(action, np.ndarray) and action.dtype == np.float32:  # the hot path
        array = action
    else:
        array = _to_float32(action, shape, what)
    if array.shape != shape:
        raise ActionError(f"{what} must have shape {shape}, got shape {array.shape}")
    if not array.flags.c_contiguous:
        array = np.ascontiguousarray(array)
    return array


def check_seed(seed: Any, what: str = "seed") -> int | None:
    """``seed`` as an int in [0, 2**64), or None.

    Raises:
        ConfigError: anything else (a float, a string, a negative or too large int, ...).
    """
    if seed is None:
        return None
    if isinstance(seed, (int, np.integer)):
        value = int(seed)
        if 0 <= value < SEED_LIMIT:
            return value
        raise ConfigError(f"{what} must be an int in [0, 2**64), got {value}")
    raise ConfigError(f"{what} must be an int in [0, 2**64) or None, got {seed!r}")


def check_int(value: Any, what: str, low: int, high: int | None = None) -> int:
    """``value`` as an int in ``low..=high`` (no upper bound when ``high`` is None).

    Raises:
        ConfigError: Not a Python or NumPy int (a bool, a float, a string, ...), or out of range;
            the message names ``what`` and the range.
    """
    span = f"{low}..={high}" if high is not None else f">= {low}"
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ConfigError(f"{what} must be an int ({span}), got {type(value).__name__}: {value!r}")
    number = int(value)
    if number < low or (high is not None and number > high):
        raise ConfigError(f"{what} must be an int in {span}, got {number}")
    return number


def check_world_index(index: Any, n: int, what: str = "index") -> int:
    """``index`` as a world index in ``0..n - 1``.

    Raises:
        ConfigError: Not an int, or no such world (the message says how many there are).
    """
    if isinstance(index, bool) or not isinstance(index, (int, np.integer)):
        raise ConfigError(f"{what} must be an int, got {type(index).__name__}: {index!r}")
    if not 0 <= int(index) < n:
        raise ConfigError(f"{what} must be a world index in 0..{n - 1}, got {int(index)}")
    return int(index)


def check_options(options: Any, what: str = "reset(options=...)") -> Mapping[str, Any] | None:
    """``options`` of a reset: None or a mapping (its keys are the env's to read).

    Raises:
        ConfigError: Anything else.
    """
    if options is None or isinstance(options, Mapping):
        return options
    raise ConfigError(f"{what} takes a dict or None, got {type(options).__name__}")


def check_world_seeds(seeds: Any, n: int) -> list[int | None]:
    """A per-world seed sequence (list, tuple or 1-D array) of ``n`` ints or None.

    Raises:
        ConfigError: not such a sequence, wrong length, or a bad seed (the message says which).
    """
    is_sequence = isinstance(seeds, (list, tuple)) or (
        isinstance(seeds, np.ndarray) and seeds.ndim == 1
    )
    if not is_sequence:
        raise ConfigError(
            f"reset(seed=...) takes an int, None, or a sequence of {n} seeds (one per world), "
            f"got {type(seeds).__name__}: {seeds!r}"
        )
    if len(seeds) != n:
        raise ConfigError(
            f"reset(seed=...) takes an int, None, or a sequence of {n} seeds "
            f"(one per world), got a sequence of {len(seeds)}"
        )
    return [check_seed(seed, f"seed of world {index}") for index, seed in enumerate(seeds)]


def check_reset_mask(mask: Any, n: int) -> npt.NDArray[np.bool_]:
    """``mask`` checked as Gymnasium's vector envs check ``options["reset_mask"]``: a NumPy
    array of dtype bool and shape (n,) with at least one True.

    Raises:
        ConfigError: Not a NumPy array, another dtype or shape, or no True value (the message
            says which; Gymnasium raises TypeError or ValueError for the same masks).
    """
    what = 'reset(options={"reset_mask": mask})'
    if not isinstance(mask, np.ndarray):
        raise ConfigError(
            f"{what}: mask must be a numpy array of dtype bool and shape ({n},), "
            f"got {type(mask).__name__}"
        )
    if mask.dtype != np.bool_:
        raise ConfigError(f"{what}: mask must have dtype bool, got dtype {mask.dtype}")
    if mask.shape != (n,):
        raise ConfigError(f"{what}: mask must have shape ({n},) (one per world), got {mask.shape}")
    if not mask.any():
        raise ConfigError(
            f"{what}: mask has no True value, so it resets no world; "
            "mark at least one world, or do not reset"
        )
    return mask


__all__ = [
    "SEED_LIMIT",
    "as_action_array",
    "check_int",
    "check_options",
    "check_reset_mask",
    "check_seed",
    "check_world_index",
    "check_world_seeds",
]
