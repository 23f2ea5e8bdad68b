"""The declared dependencies: pyproject.toml's floors, the pinned floor set, and the optional
packages that no other test exercises (rich for SB3's progress bar, imageio for MP4 files).

``make test-floors`` runs the whole suite in a Python 3.10 venv resolved with
``constraints/floors.txt`` (every declared floor pinned with ``==``) and sets
``KHEPERA_GYM_FLOORS=1``; there the installed versions must be the floors themselves, elsewhere
they must satisfy pyproject.toml's specifiers.
"""

from __future__ import annotations

import os
import re
import subprocess
from importlib import metadata
from pathlib import Path

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10: tomli, a dependency there
    import tomli as tomllib

import numpy as np
import pytest
from conftest import NAV_ID
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name
from packaging.version import Version

from khepera_gym.render import save_video

ROOT = Path(__file__).resolve().parents[1]
FLOORS_FILE = ROOT / "constraints" / "floors.txt"
#: Declared without a floor: a developer tool (`make lint`), never imported by the package or
#: the tests, so no floor of it can be tested.
UNFLOORED = {"ruff"}


def _declared() -> list[Requirement]:
    """Every requirement of pyproject.toml: the dependencies and those of each extra."""
    project = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    lines = list(project["dependencies"])
    for extra in project["optional-dependencies"].values():
        lines += extra
    return [Requirement(line) for line in lines]


def _floor(requirement: Requirement) -> Version | None:
    """The version of the requirement's one ``>=`` clause (None without one)."""
    floors = [Version(s.version) for s in requirement.specifier if s.operator == ">="]
    assert len(floors) <= 1, f"{requirement}: more than one floor"
    return floors[0] if floors else None


def _pins() -> dict[str, Version]:
    """``name==version`` lines of constraints/floors.txt, by canonical name."""
    pins: dict[str, Version] = {}
    for line in FLOORS_FILE.read_text(encoding="utf-8").splitlines():
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        name, separator, version = line.partition("==")
        assert separator and ";" not in line, f"floors.txt: {line!r} is not a name==version pin"
        key = canonicalize_name(name.strip())
        assert key not in pins, f"floors.txt pins {key} twice"
        pins[key] = Version(version.strip())
    return pins


def test_every_declared_dependency_has_a_floor_pinned_in_the_floor_constraints() -> None:
    pins = _pins()
    for requirement in _declared():
        key = canonicalize_name(requirement.name)
        floor = _floor(requirement)
        if key in UNFLOORED:
            assert floor is None and key not in pins, f"{key} is listed as unfloored"
            continue
        assert floor is not None, f"pyproject.toml: {requirement} declares no floor (>=)"
        assert key in pins, f"constraints/floors.txt does not pin {key} (floor {floor})"
        assert pins[key] == floor, f"{key}: pyproject.toml's floor {floor}, floors.txt {pins[key]}"


def test_installed_versions_are_the_floors_in_the_floor_run_and_allowed_elsewhere() -> None:
    in_floor_run = os.environ.get("KHEPERA_GYM_FLOORS") == "1"
    pins = _pins()
    checked = 0
    for requirement in _declared():
        if requirement.marker is not None and not requirement.marker.evaluate({"extra": ""}):
            continue  # e.g. tomli on Python >= 3.11
        key = canonicalize_name(requirement.name)
        installed = Version(metadata.version(requirement.name))
        checked += 1
        if in_floor_run and key not in UNFLOORED:
            assert installed == pins[key], f"{key} {installed} installed, floor {pins[key]}"
        else:
            assert requirement.specifier.contains(installed, prereleases=True), (
                f"{key} {installed} installed, pyproject.toml asks {requirement}"
            )
    assert checked >= 10


@pytest.mark.filterwarnings("ignore::tqdm.TqdmExperimentalWarning")  # tqdm.rich is "experimental"
def test_sb3_training_draws_its_progress_bar_with_rich(tmp_path: Path, capsys) -> None:
    """The sb3 extra's rich (through tqdm.rich) draws SB3's bar; the other tests train without."""
    from khepera_gym.train import train

    train(
        NAV_ID,
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
