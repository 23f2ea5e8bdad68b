"""Builds and runs of the generated robot programs against the simulated libkhepera
(tests/fake_libkhepera/), on this PC or for the Khepera IV's ARM processor under emulation
(:mod:`khepera_gym.robot.export.toolchain`): the helpers of the tests that run them.

A program built here links the fake library's simulated clock (fake_clock.c) in place of the
program's own khepera_clock.c, so that a run of minutes of robot time takes a fraction of a
second. Every build has warnings as errors and the generated Makefile's ``-std=gnu99``; the ARM
build adds K-Team's Poky flags (ARMv7-A, hard float, NEON) and links statically, and runs under
``qemu-arm``.
"""

from __future__ import annotations

import os
import struct
import subprocess
from collections.abc import Mapping, Sequence
from pathlib import Path

import pytest

from khepera_gym.robot.export import C_SOURCES, Target, arm_target, host_target

#: The simulated libkhepera.
FAKE = Path(__file__).resolve().parent / "fake_libkhepera"
#: Warnings are errors in every build of the tests.
WARNINGS = ("-Wall", "-Wextra", "-Werror")
#: The C dialect of the generated Makefile's robot build (libkhepera's headers need GNU C).
ROBOT_STD = "-std=gnu99"
#: The targets the tests build for.
TARGETS = {"host": host_target("cc", ("-O2",)), "arm": arm_target()}
#: Why a test of the robot's processor is skipped, when it is.
ARM_SKIP = (
    "needs the robot's cross compiler and an ARM emulator ({reason}); .ci/run installs them, so "
    "CI never skips this"
)


#: Set (by .ci/run) where a missing ARM toolchain is a failure rather than a skip.
REQUIRE_ARM = "KHEPERA_GYM_REQUIRE_ARM"


def target(name: str) -> Target:
    """The target ``name``, or a skip saying what is missing (a failure where the environment
    sets :data:`REQUIRE_ARM`)."""
    chosen = TARGETS[name]
    reason = chosen.missing()
    if reason is not None:
        message = ARM_SKIP.format(reason=reason) if name == "arm" else reason
        if os.environ.get(REQUIRE_ARM):
            pytest.fail(f"{REQUIRE_ARM} is set: {message}")
        pytest.skip(message)
    return chosen


def archiver(chosen: Target) -> str:
    """The ``ar`` of a target's compiler (arm-linux-gnueabihf-ar beside arm-linux-gnueabihf-gcc)."""
    return chosen.compiler[: -len("gcc")] + "ar" if chosen.compiler.endswith("-gcc") else "ar"


def build_on_fake(
    chosen: Target,
    out_dir: Path,
    main: str,
    sources: Sequence[str],
    name: str,
    **defines: float,
) -> Path:
    """``main`` and ``sources`` of ``out_dir`` built for ``chosen`` against the fake robot (its
    FAKE_* settings overridden by ``defines``) and its clock, warnings as errors."""
    program = out_dir / name
    command = [
        chosen.compiler,
        *chosen.flags,
        ROBOT_STD,
        *WARNINGS,
        *(f"-D{key}={value}" for key, value in defines.items()),
        f"-I{FAKE}",
        f"-I{out_dir}",
        "-o",
        str(program),
        str(out_dir / main),
        *(str(out_dir / s) for s in sources if s != "khepera_clock.c"),
        str(FAKE / "fake_khepera4.c"),
        str(FAKE / "fake_clock.c"),
        *chosen.link_flags,
        "-lm",
    ]
    subprocess.run(command, check=True, capture_output=True, text=True)
    return program


def build_check(chosen: Target, out_dir: Path, name: str) -> Path:
    """``export_check`` of the export in ``out_dir`` built for ``chosen``, warnings as errors,
    C99 as the export's own check builds it."""
    program = out_dir / name
    command = [
        chosen.compiler,
        *chosen.flags,
        "-std=c99",
        *WARNINGS,
        "-o",
        str(program),
        *(str(out_dir / s) for s in ("export_check.c", *C_SOURCES)),
        *chosen.link_flags,
        "-lm",
    ]
    subprocess.run(command, check=True, capture_output=True, text=True)
    return program


def fake_library(chosen: Target, directory: Path) -> Path:
    """The fake robot as ``libkhepera.a`` built for ``chosen``, in ``directory``."""
    directory.mkdir(parents=True, exist_ok=True)
    objects = directory / "fake_khepera4.o"
    subprocess.run(
        [
            chosen.compiler,
            *chosen.flags,
            ROBOT_STD,
            *WARNINGS,
            "-c",
            f"-I{FAKE}",
            "-o",
            str(objects),
            str(FAKE / "fake_khepera4.c"),
        ],
        check=True,
        capture_output=True,
        text=True,
    )
    library = directory / "libkhepera.a"
    subprocess.run([archiver(chosen), "rcs", str(library), str(objects)], check=True)
    return library


def run(
    chosen: Target,
    program: Path,
    *arguments: str,
    environment: Mapping[str, str] | None = None,
    stdin: str = "",
    check: bool = True,
    timeout: float = 120,
) -> subprocess.CompletedProcess[str]:
    """Runs a built program (under the target's emulator), the fake robot's variables set."""
    return subprocess.run(
        chosen.command(str(program), *arguments),
        env={**os.environ, **(environment or {})},
        input=stdin,
        capture_output=True,
        text=True,
        check=check,
        timeout=timeout,
    )


def elf_machine(path: Path) -> tuple[int, int, int]:
    """An ELF file's class (1: 32-bit), machine (40: ARM) and flags (ARM: EABI version in the
    top byte, 0x400 the hard-float ABI)."""
    header = path.read_bytes()[:52]
    assert header[:4] == b"\x7fELF", f"{path} is not an ELF file"
    machine = struct.unpack_from("<H", header, 18)[0]
    flags = struct.unpack_from("<I", header, 36)[0]
    return header[4], machine, flags


def sdk_include(sdk: Path, scratch: Path) -> Path:
    """The folder to pass with -I so that ``#include <khepera/khepera.h>`` finds the K-Team
    headers of ``sdk``: an install (``include/khepera/khepera.h``, or ``khepera/khepera.h``), or
    a libkhepera source tree (``khepera.h`` among the sources: linked as ``scratch/khepera``)."""
    for include in (sdk / "include", sdk):
        if (include / "khepera" / "khepera.h").is_file():
            return include
    if (sdk / "khepera.h").is_file():
        scratch.mkdir(parents=True, exist_ok=True)
        (scratch / "khepera").symlink_to(sdk.resolve(), target_is_directory=True)
        return scratch
    raise FileNotFoundError(
        f"KHEPERA_SDK={sdk}: no khepera.h there, in khepera/ or in include/khepera/ (give a "
        "libkhepera 2.1 source tree, e.g. libkhepera-2.1/, or its install)"
    )
