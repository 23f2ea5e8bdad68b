"""Where the generated C programs are built and run: the PC the export runs on, or the Khepera
IV's own processor, emulated.

The robot runs an ARM Cortex-A8 (ARMv7-A, hard float, NEON; a Gumstix Overo, docs/robot.md §6).
K-Team builds libkhepera 2.1 and its programs with its Poky 1.8 toolchain, whose compiler is
``arm-poky-linux-gnueabi-gcc -march=armv7-a -mfloat-abi=hard -mfpu=neon -mtune=cortex-a8`` with
``CFLAGS = -O2 -pipe -g -feliminate-unused-debug-types`` (libkhepera-2.1/Makefile).
:func:`arm_target` builds with those flags and Debian's cross compiler for the same ABI
(``arm-linux-gnueabihf-gcc``, package ``gcc-arm-linux-gnueabihf``), statically linked so that
user-mode emulation runs the result without the robot's libraries (``qemu-arm``, package
``qemu-user``). What this checks: the robot's compiler flags, its 32-bit ``long`` and pointers,
its unsigned ``char``, its floating point; not the robot's kernel, timing or libkhepera itself.

Threading: none (child processes, one at a time).
"""

from __future__ import annotations

import dataclasses
import shutil
from collections.abc import Sequence

#: The processor flags of K-Team's Poky toolchain for the Khepera IV.
ROBOT_ARCH_FLAGS = ("-march=armv7-a", "-mfloat-abi=hard", "-mfpu=neon", "-mtune=cortex-a8")
#: Its CFLAGS.
POKY_CFLAGS = ("-O2", "-pipe", "-g", "-feliminate-unused-debug-types")
#: Its LDFLAGS.
POKY_LDFLAGS = ("-Wl,-O1", "-Wl,--hash-style=gnu", "-Wl,--as-needed")
#: Debian's cross compiler for the robot's ABI (hard-float ARMv7 Linux, glibc).
ARM_CROSS_COMPILER = "arm-linux-gnueabihf-gcc"
#: User-mode emulation of an ARM Linux process.
ARM_EMULATOR = "qemu-arm"
#: How to install both on Debian and Ubuntu.
ARM_PACKAGES = "apt-get install gcc-arm-linux-gnueabihf qemu-user"


@dataclasses.dataclass(frozen=True)
class Target:
    """A machine the C programs are built for and run on."""

    #: "host" or "arm".
    name: str
    #: The C compiler.
    compiler: str
    #: Flags before the sources: the processor's and the optimisation.
    flags: tuple[str, ...]
    #: Flags after the sources (linking).
    link_flags: tuple[str, ...]
    #: What runs a built program ((): the program runs by itself).
    runner: tuple[str, ...]

    def missing(self) -> str | None:
        """Why the target cannot be used here (a tool not on PATH), or None."""
        hint = f" (Debian: {ARM_PACKAGES})" if self.name == "arm" else ""
        if shutil.which(self.compiler) is None:
            return f"no C compiler {self.compiler!r} on PATH{hint}"
        if self.runner and shutil.which(self.runner[0]) is None:
            return f"no emulator {self.runner[0]!r} on PATH{hint}"
        return None

    def command(self, program: str, *arguments: str) -> list[str]:
        """The command line running a built ``program``."""
        return [*self.runner, program, *arguments]


def host_target(compiler: str = "cc", flags: Sequence[str] = ("-O2",)) -> Target:
    """The machine running khepera_gym, with its C compiler."""
    return Target("host", compiler, tuple(flags), (), ())


def arm_target(compiler: str = ARM_CROSS_COMPILER, emulator: str = ARM_EMULATOR) -> Target:
    """The Khepera IV's processor: K-Team's flags, a static build, run under ``emulator``."""
    return Target(
        "arm",
        compiler,
        (*ROBOT_ARCH_FLAGS, *POKY_CFLAGS),
        (*POKY_LDFLAGS, "-static"),
        (emulator,),
    )


__all__ = [
    "ARM_CROSS_COMPILER",
    "ARM_EMULATOR",
    "ARM_PACKAGES",
    "POKY_CFLAGS",
    "POKY_LDFLAGS",
    "ROBOT_ARCH_FLAGS",
    "Target",
    "arm_target",
    "host_target",
]
