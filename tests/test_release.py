"""One version number everywhere a user reads it: ``Cargo.toml`` is where a release sets it
(docs/changelog.md, "How a release is cut"); the lock file, the built package, the sdist, the
docs and the changelog's top release must say the same. ``make wheel`` checks the wheel."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
import tarfile
from pathlib import Path

import pytest

import khepera_gym
from khepera_gym.config import tomllib

ROOT = Path(__file__).resolve().parents[1]
CHANGELOG = ROOT / "docs" / "changelog.md"
#: A release heading: ``## 0.2.0 (2026-12-07)``.
RELEASE = re.compile(r"^## (\d+\.\d+\.\d+) \((\d{4}-\d{2}-\d{2})\)$", re.MULTILINE)


def cargo_version() -> str:
    return tomllib.loads((ROOT / "Cargo.toml").read_text(encoding="utf-8"))["package"]["version"]


def top_release(changelog: str) -> str:
    """The newest release the changelog names: its first release heading, under which nothing
    but an ``Unreleased`` section may come before it."""
    headings = re.findall(r"^## (.+)$", changelog, re.MULTILINE)
    releases = [h for h in headings if RELEASE.match(f"## {h}")]
    if not releases:
        raise AssertionError("the changelog names no release (`## X.Y.Z (YYYY-MM-DD)`)")
    before = headings[: headings.index(releases[0])]
    extra = [h for h in before if h not in ("How a release is cut", "Unreleased")]
    if extra:
        raise AssertionError(f"sections above the newest release: {extra}")
    return releases[0].split(" ")[0]


def test_top_release_parser_reads_the_first_release_and_refuses_others_above_it() -> None:
    page = "# Changelog\n\n## Unreleased\n\n- x\n\n## 1.2.3 (2027-01-02)\n\n## 1.2.2 (2026-01-01)\n"
    assert top_release(page) == "1.2.3"
    with pytest.raises(AssertionError, match="no release"):
        top_release("# Changelog\n\n## Unreleased\n")
    with pytest.raises(AssertionError, match="above the newest release"):
        top_release("## Fixes\n\n## 1.2.3 (2027-01-02)\n")


def test_the_changelog_top_release_is_cargos_version() -> None:
    assert top_release(CHANGELOG.read_text(encoding="utf-8")) == cargo_version()


def test_the_lock_file_and_the_built_package_carry_cargos_version() -> None:
    lock = tomllib.loads((ROOT / "Cargo.lock").read_text(encoding="utf-8"))
    (ours,) = [p for p in lock["package"] if p["name"] == "khepera_gym"]
    assert ours["version"] == cargo_version()
    assert khepera_gym.__version__ == cargo_version(), (
        "the extension was built from another Cargo.toml version: rebuild (make develop)"
    )


def test_pyproject_and_the_docs_take_the_version_from_the_package() -> None:
    project = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    assert "version" not in project and "version" in project["dynamic"]
    conf = (ROOT / "docs" / "conf.py").read_text(encoding="utf-8")
    assert re.search(r"^release = khepera_gym\.__version__$", conf, re.MULTILINE)


def test_the_sdist_is_named_and_labelled_with_cargos_version(tmp_path: Path) -> None:
    maturin = shutil.which("maturin", path=str(Path(sys.executable).parent)) or shutil.which(
        "maturin"
    )
    if maturin is None:
        pytest.skip("maturin is not installed here (the main test leg has it)")
    subprocess.run(
        [maturin, "sdist", "--out", str(tmp_path)], cwd=ROOT, check=True, capture_output=True
    )
    (sdist,) = tmp_path.glob("*.tar.gz")
    assert sdist.name == f"khepera_gym-{cargo_version()}.tar.gz"
    with tarfile.open(sdist) as archive:
        info = archive.extractfile(f"khepera_gym-{cargo_version()}/PKG-INFO")
        assert info is not None
        assert f"\nVersion: {cargo_version()}\n" in info.read().decode("utf-8")
