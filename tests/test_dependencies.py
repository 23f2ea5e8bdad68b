"""The declared dependencies: pyproject.toml's floors, the pinned floor sets, and the optional
packages that no other test exercises (rich for SB3's progress bar, imageio for MP4 files).

``make test-floors`` runs on Python 3.10, in steps that each set ``KHEPERA_GYM_FLOORS`` to their
name (:data:`FLOOR_STEPS`): the whole suite in a venv resolved with ``constraints/floors.txt``
(every declared floor but the rllib extra's pinned with ``==``), then tests/test_rllib.py and this
file after the same venv took ``constraints/floors-rllib.txt``. In a step the installed versions
must be the pinned ones; elsewhere they must satisfy pyproject.toml's specifiers.
"""

from __future__ import annotations

import os
import re
import subprocess
import sysconfig
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10: tomli, a dependency there
    import tomli as tomllib

import numpy as np
import pytest
from conftest import LATEST
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name
from packaging.version import Version

from khepera_gym.render import save_video

ROOT = Path(__file__).resolve().parents[1]
CONSTRAINTS_DIR = ROOT / "constraints"
#: Declared without a floor: a developer tool (`make lint`), never imported by the package or
#: the tests, so no floor of it can be tested.
UNFLOORED = {"ruff"}
#: The parts of pyproject.toml: "" for the dependencies, else an extra's name.
DEPENDENCIES = ""
#: Extras no floor step installs: the docs extra builds the site (`make docs`) on Python 3.11
#: only (Sphinx 9 needs it) and is never imported by the package or the tests; its floors are
#: the versions the site was built with. The typecheck extra (mypy, basedpyright) checks a
#: user's script in tests/test_static_types.py, which skips where it is missing; its floors are
#: the versions that test was written against. Where it is installed, its floors must hold.
UNSTEPPED_PARTS = frozenset({"docs", "typecheck"})
#: Installed in a floor step without a pin: the project, the venv's own installers and ruff.
UNPINNED = {"khepera-gym", "pip", "setuptools", *UNFLOORED}


@dataclass(frozen=True)
class FloorStep:
    """One step of ``make test-floors``.

    Attributes:
        constraints: Files in constraints/ whose pins the step installs, a later file's pin of a
            package replacing an earlier one's.
        floored: The parts whose floors the last file pins.
        installed: The parts installed in the step.
    """

    constraints: tuple[str, ...]
    floored: frozenset[str]
    installed: frozenset[str]


_FIRST_STEP_PARTS = frozenset(
    {DEPENDENCIES, "test", "sb3", "render", "export", "calibrate", "torchrl", "benchmarl", "report"}
)
#: By ``KHEPERA_GYM_FLOORS``. Ray 2.52 pins gymnasium 1.1.1 and needs a protobuf that the export
#: extra's onnx 1.12 refuses, so the rllib step moves gymnasium and uninstalls the export extra.
FLOOR_STEPS = {
    "floors": FloorStep(("floors.txt",), _FIRST_STEP_PARTS, _FIRST_STEP_PARTS),
    "rllib": FloorStep(
        ("floors.txt", "floors-rllib.txt"),
        frozenset({"rllib"}),
        _FIRST_STEP_PARTS - {"export"} | {"rllib"},
    ),
}


def _declared(parts: frozenset[str] | None = None) -> list[Requirement]:
    """The requirements of pyproject.toml's dependencies and extras (of ``parts`` if given)."""
    project = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    by_part = {DEPENDENCIES: project["dependencies"], **project["optional-dependencies"]}
    if parts is not None:
        assert parts <= by_part.keys(), f"pyproject.toml has no extras {parts - by_part.keys()}"
    return [
        Requirement(line)
        for part, lines in by_part.items()
        if parts is None or part in parts
        for line in lines
    ]


def _floor(requirement: Requirement) -> Version | None:
    """The version of the requirement's one ``>=`` clause (None without one)."""
    floors = [Version(s.version) for s in requirement.specifier if s.operator == ">="]
    assert len(floors) <= 1, f"{requirement}: more than one floor"
    return floors[0] if floors else None


def _pins(file_name: str) -> dict[str, Version]:
    """``name==version`` lines of a file in constraints/, by canonical name."""
    pins: dict[str, Version] = {}
    for line in (CONSTRAINTS_DIR / file_name).read_text(encoding="utf-8").splitlines():
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        name, separator, version = line.partition("==")
        assert separator and ";" not in line, f"{file_name}: {line!r} is not a name==version pin"
        key = canonicalize_name(name.strip())
        assert key not in pins, f"{file_name} pins {key} twice"
        pins[key] = Version(version.strip())
    return pins


def _installed_version(name: str) -> Version | None:
    try:
        return Version(metadata.version(name))
    except metadata.PackageNotFoundError:
        return None


def test_every_part_of_pyproject_has_its_floors_pinned_by_one_floor_step() -> None:
    project = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    parts = [
        DEPENDENCIES,
        *(p for p in project["optional-dependencies"] if p not in UNSTEPPED_PARTS),
    ]
    floored = [part for step in FLOOR_STEPS.values() for part in step.floored]
    assert sorted(floored) == sorted(parts)
    for step in FLOOR_STEPS.values():
        assert step.floored <= step.installed


@pytest.mark.parametrize("step_name", FLOOR_STEPS)
def test_every_declared_dependency_has_a_floor_pinned_in_the_floor_constraints(
    step_name: str,
) -> None:
    step = FLOOR_STEPS[step_name]
    file_name = step.constraints[-1]
    pins = _pins(file_name)
    for requirement in _declared(step.floored):
        key = canonicalize_name(requirement.name)
        floor = _floor(requirement)
        if key in UNFLOORED:
            assert floor is None and key not in pins, f"{key} is listed as unfloored"
            continue
        assert floor is not None, f"pyproject.toml: {requirement} declares no floor (>=)"
        assert key in pins, f"constraints/{file_name} does not pin {key} (floor {floor})"
        assert pins[key] == floor, f"{key}: pyproject.toml's floor {floor}, {file_name} {pins[key]}"


def test_installed_versions_are_the_pinned_ones_in_a_floor_step_and_allowed_elsewhere() -> None:
    step_name = os.environ.get("KHEPERA_GYM_FLOORS")
    if step_name is None:
        checked = 0
        optional = {canonicalize_name(r.name) for r in _declared(UNSTEPPED_PARTS)}
        for requirement in _declared():
            if requirement.marker is not None and not requirement.marker.evaluate({"extra": ""}):
                continue  # e.g. tomli on Python >= 3.11
            name = canonicalize_name(requirement.name)
            if name in optional and _installed_version(requirement.name) is None:
                continue  # the docs extra, not installed here
            installed = Version(metadata.version(requirement.name))
            assert requirement.specifier.contains(installed, prereleases=True), (
                f"{requirement.name} {installed} installed, pyproject.toml asks {requirement}"
            )
            checked += 1
        assert checked >= 20
        return
    assert step_name in FLOOR_STEPS, f"KHEPERA_GYM_FLOORS={step_name!r}: not one of {FLOOR_STEPS}"
    step = FLOOR_STEPS[step_name]
    pins: dict[str, Version] = {}
    for file_name in step.constraints:
        pins.update(_pins(file_name))
    for requirement in _declared(step.installed):
        if requirement.marker is not None and not requirement.marker.evaluate({"extra": ""}):
            continue
        key = canonicalize_name(requirement.name)
        if key in UNFLOORED:
            continue
        installed = _installed_version(requirement.name)
        assert installed == pins[key], f"{key} {installed} installed, pinned {pins[key]}"
    # The rest of the resolve too: nothing drifted from the pins, nothing came in unpinned. Only
    # the venv's site-packages: Ray puts its own copy of psutil on sys.path once imported.
    site_packages = sorted({sysconfig.get_path("purelib"), sysconfig.get_path("platlib")})
    installed_keys = {
        canonicalize_name(d.metadata["Name"]) for d in metadata.distributions(path=site_packages)
    }
    assert installed_keys - pins.keys() - UNPINNED == set()
    for key in installed_keys - UNPINNED:
        installed = _installed_version(key)
        assert installed == pins[key], f"{key} {installed} installed, pinned {pins[key]}"


@pytest.mark.filterwarnings("ignore::tqdm.TqdmExperimentalWarning")  # tqdm.rich is "experimental"
def test_sb3_training_draws_its_progress_bar_with_rich(tmp_path: Path, capsys) -> None:
    """The sb3 extra's rich (through tqdm.rich) draws SB3's bar; the other tests train without."""
    from khepera_gym.learning.train import train

    train(
        LATEST["nav"],
        "ppo",
        timesteps=256,
        n_envs=4,
        out_dir=tmp_path,
        eval_freq=0,
        eval_episodes=2,
        num_threads=1,
        verbose=0,
        progress_bar=True,
        overrides={"n_steps": 64, "batch_size": 64, "n_epochs": 1},
    )
    output = capsys.readouterr().out
    assert "progress bar off" not in output
    assert "256/256" in output and "100%" in output, output


def test_save_video_writes_an_mp4_that_decodes_frame_for_frame(tmp_path: Path) -> None:
    """The render extra's imageio + imageio-ffmpeg write MP4s (RecordVideo's test uses moviepy)."""
    import imageio_ffmpeg

    height, width = 48, 64
    levels = np.random.default_rng(0).integers(0, 256, size=12)
    frames = [np.full((height, width, 3), level, np.uint8) for level in levels]
    path = save_video(frames, tmp_path / "run.mp4", fps=10)
    # Decoded by the ffmpeg that imageio-ffmpeg bundles, to raw RGB (imageio's own reader leaves
    # ffmpeg's pipes open in older releases).
    ffmpeg = imageio_ffmpeg.get_ffmpeg_exe()
    decoded = subprocess.run(
        [ffmpeg, "-v", "error", "-i", str(path), "-f", "rawvideo", "-pix_fmt", "rgb24", "-"],
        capture_output=True,
        check=True,
    ).stdout
    read = np.frombuffer(decoded, np.uint8).reshape(-1, height, width, 3)
    assert len(read) == len(frames)
    # ffmpeg -i with no output file prints the streams ("..., 64x48, ..., 10 fps, ...") and fails.
    streams = subprocess.run([ffmpeg, "-i", str(path)], capture_output=True, text=True)
    assert re.search(r"\b10 fps\b", streams.stderr), streams.stderr
    for level, frame in zip(levels, read, strict=True):
        # H.264 is lossy and stores YUV: a flat grey comes back within a few levels.
        assert abs(float(frame.mean()) - float(level)) < 4.0
