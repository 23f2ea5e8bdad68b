"""The cross-cutting tests cover every registered env: no id and no PettingZoo module is left out.

The tests that hold for every env (world i ≡ single env seeded s + i, one ≡ two threads, saved
states, Gymnasium's env checker, PettingZoo's API and seed tests) are parametrized from the
registries (``registered_ids()``, ``khepera_gym.pettingzoo.modules()``). This file collects them
as pytest does (``--collect-only``, in a subprocess) and checks that each one's parameters name
every registered id or module: a test whose list was written by hand, or filtered, fails here.
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import ALL_IDS, PETTINGZOO_MODULES

import khepera_gym.pettingzoo
from khepera_gym.registration import registered_ids

TESTS = Path(__file__).parent
#: The tests that must run on every registered Gymnasium id: file → test functions.
EVERY_ID = {
    "test_determinism.py": [
        "test_batch_world_equals_single_env_with_seed_plus_index_across_autoreset",
        "test_batch_results_do_not_depend_on_thread_count",
    ],
    "test_vector_reset_mask.py": [
        "test_autoreset_mode_defaults_to_next_step_and_is_shown_in_metadata",
        "test_masked_reset_leaves_unmasked_worlds_bit_for_bit_unchanged",
        "test_masked_world_equals_single_env_reset_with_seed_plus_index",
    ],
    "test_state.py": [
        "test_single_env_restored_state_replays_bit_for_bit",
        "test_vector_env_restored_state_replays_bit_for_bit",
        "test_pickled_env_continues_like_the_original",
    ],
    "test_api.py": ["test_gymnasium_env_checker_passes_without_warnings"],
}
#: The tests that must run on every versioned PettingZoo module: file → test functions.
EVERY_MODULE = {
    "test_pettingzoo.py": [
        "test_parallel_api_test_passes",
        "test_aec_api_test_passes",
        "test_seed_tests_pass",
    ],
    "test_state.py": ["test_pettingzoo_env_pickles_mid_episode"],
}


def _collected(files: list[str]) -> dict[str, list[str]]:
    """Test function → the parameter ids pytest collects for it in ``files``."""
    result = subprocess.run(
        [sys.executable, "-m", "pytest", "--collect-only", "-q", "-p", "no:cacheprovider"]
        + [str(TESTS / name) for name in files],
        capture_output=True,
        text=True,
        cwd=TESTS.parent,
        check=False,
    )
    assert result.returncode == 0, result.stdout[-2000:] + result.stderr[-2000:]
    params: dict[str, list[str]] = {}
    for line in result.stdout.splitlines():
        match = re.fullmatch(r"tests/(\S+\.py)::(\w+)\[(.+)\]", line.strip())
        if match:
            params.setdefault(match[2], []).append(match[3])
    return params


@pytest.fixture(scope="module")
def collected() -> dict[str, list[str]]:
    return _collected(sorted({*EVERY_ID, *EVERY_MODULE}))


def test_the_registries_are_what_the_tests_run_over() -> None:
    assert [env_id for ids in registered_ids().values() for env_id in ids] == ALL_IDS
    assert list(PETTINGZOO_MODULES) == list(khepera_gym.pettingzoo.modules())
    assert len(ALL_IDS) == len(set(ALL_IDS)) > 0
    assert PETTINGZOO_MODULES


@pytest.mark.parametrize(
    "test", [test for tests in EVERY_ID.values() for test in tests], ids=lambda test: test
)
def test_every_registered_id_is_in_each_cross_cutting_test(
    collected: dict[str, list[str]], test: str
) -> None:
    params = collected.get(test, [])
    missing = [env_id for env_id in ALL_IDS if not any(env_id in param for param in params)]
    assert not missing, f"{test} does not run on {missing}"


@pytest.mark.parametrize(
    "test", [test for tests in EVERY_MODULE.values() for test in tests], ids=lambda test: test
)
def test_every_pettingzoo_module_is_in_each_cross_cutting_test(
    collected: dict[str, list[str]], test: str
) -> None:
    params = collected.get(test, [])
    missing = [name for name in PETTINGZOO_MODULES if name not in params]
    assert not missing, f"{test} does not run on {missing} (with the module's defaults)"
