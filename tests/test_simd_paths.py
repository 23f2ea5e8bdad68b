"""Every vector path gives the golden digests (issue 54): the hot kernels run on the widest
path the CPU has (``khepera_gym.simd_path()``: ``portable``, ``avx2`` or ``avx512``), and each
path this CPU has is forced in turn and replays every recorded trajectory bit for bit (the
cases of tests/golden.py: every Gymnasium id, single and vector, every PettingZoo module, the
swarm scene split both ways, on two threads where they step in parallel). A path the CPU lacks
cannot be forced: its test skips and says so, and the session's summary names the paths that
ran (tests/conftest.py).

An older CPU's libm is stood in for by glibc's tunables (``glibc.cpu.hwcaps=-AVX2,-FMA``
selects the SSE2 builds of sinf, cosf and exp that a CPU without AVX2 and FMA would run): the
digests hold there too, in a fresh process.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from golden import cases, load

import khepera_gym
from khepera_gym import _core
from khepera_gym.errors import ConfigError

RECORDED = load()
PATHS = dict(_core.simd_paths())
#: What ran on each path, for the session's summary (tests/conftest.py prints it).
RAN: dict[str, str] = {}


@pytest.fixture
def restore_path():
    """Puts the kernels back on the path they ran before the test forced another."""
    before = _core.simd_path()
    yield
    _core.force_simd(before)


@pytest.mark.filterwarnings("ignore:.*is out of date:DeprecationWarning")
@pytest.mark.parametrize("path", list(PATHS))
def test_every_golden_digest_holds_on_the_path(path: str, restore_path: None) -> None:
    if not PATHS[path]:
        RAN[path] = "skipped: this CPU lacks its units"
        pytest.skip(f"this CPU has no {path} units: its kernels cannot be forced here")
    _core.force_simd(path)
    assert khepera_gym.simd_path() == path
    differ = [name for name, case in cases() if case() != RECORDED[name]]
    assert not differ, f"on the {path} path these no longer replay bit for bit: {differ}"
    RAN[path] = f"{len(RECORDED)} golden digests hold"


def test_the_widest_path_the_cpu_has_runs_unless_one_is_forced() -> None:
    widest = [name for name, have in PATHS.items() if have][-1]
    if "KHEPERA_GYM_SIMD" not in os.environ:
        env = {k: v for k, v in os.environ.items() if k != "KHEPERA_GYM_SIMD"}
        ran = subprocess.run(
            [sys.executable, "-c", "import khepera_gym; print(khepera_gym.simd_path())"],
            capture_output=True,
            text=True,
            env=env,
            check=True,
        )
        assert ran.stdout.strip() == widest
    assert list(PATHS) == ["portable", "avx2", "avx512"] and PATHS["portable"]


def test_an_unknown_path_or_one_the_cpu_lacks_is_a_config_error(restore_path: None) -> None:
    with pytest.raises(ConfigError, match=r'unknown vector path "avx9"; known: portable, avx2'):
        _core.force_simd("avx9")
    lacking = [name for name, have in PATHS.items() if not have]
    for name in lacking:
        with pytest.raises(ConfigError, match=f"this CPU has no {name} units"):
            _core.force_simd(name)
    # From the environment: at import, before anything runs.
    env = {**os.environ, "KHEPERA_GYM_SIMD": "sse9"}
    ran = subprocess.run(
        [sys.executable, "-c", "import khepera_gym"], capture_output=True, text=True, env=env
    )
    assert ran.returncode != 0
    assert 'ConfigError: KHEPERA_GYM_SIMD: path: unknown vector path "sse9"' in ran.stderr


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's tunables: Linux only")
def test_the_digests_hold_with_the_libm_of_a_cpu_without_avx2_and_fma() -> None:
    env = {
        **os.environ,
        "GLIBC_TUNABLES": "glibc.cpu.hwcaps=-AVX2,-FMA",
        "KHEPERA_GYM_SIMD": "portable",
    }
    tests = Path(__file__).parent
    ran = subprocess.run(
        [sys.executable, str(tests / "golden.py")],
        capture_output=True,
        text=True,
        env=env,
        cwd=tests,
    )
    assert ran.returncode == 0, ran.stdout[-2000:] + ran.stderr[-2000:]
    RAN["portable, older CPU's libm"] = "golden digests hold (glibc.cpu.hwcaps=-AVX2,-FMA)"
