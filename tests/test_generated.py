"""The generated source is current (issue 51): every versioned PettingZoo module file, the import
blocks of ``khepera_gym/pettingzoo/__init__.py`` and ``khepera_gym/envs/__init__.py`` and the
vector env classes of ``khepera_gym/vector.py`` are what ``make generated`` writes from the core's
registries, and they agree with the registries as Python sees them."""

from __future__ import annotations

from pathlib import Path

from khepera_gym import _generate, pettingzoo, registry
from khepera_gym.envs import ENV_CLASSES
from khepera_gym.pettingzoo import VERSIONED_MODULES, modules
from khepera_gym.vector import VECTOR_ENV_CLASSES


def test_generated_files_match_what_make_generated_writes() -> None:
    changed = _generate.differences()
    assert not changed, "run `make generated`; these differ: " + ", ".join(
        str(path.relative_to(_generate.PACKAGE_DIR.parent)) for path in changed
    )


def test_one_pettingzoo_file_per_family_and_version_of_its_task() -> None:
    families = {module.family: module.task for module in pettingzoo.module_infos()}
    expected = {
        f"{family}_v{version}"
        for family, task in families.items()
        for version in registry.task_versions(task)
    }
    assert set(modules()) == expected
    folder = Path(_generate.PACKAGE_DIR, "pettingzoo")
    on_disk = {path.stem for path in folder.glob("*_v*.py")}
    assert on_disk == expected
    for module in VERSIONED_MODULES:
        assert module.__file__ is not None and Path(module.__file__).parent == folder
        name = module.__name__.rpartition(".")[2]
        version = name.rpartition("_v")[2]
        env_class = next(m.env_class for m in pettingzoo.module_infos() if m.name == name)
        assert int(version) == env_class.VERSION
        assert env_class.metadata["name"] == name
        assert env_class.__module__ == module.__name__


def test_a_changed_or_missing_file_is_reported(tmp_path: Path, monkeypatch) -> None:
    # The check itself can fail: a copy of the package folder with one module edited and one
    # removed is reported as two differences.
    files, stale = _generate.expected()
    assert not stale
    edited, removed = sorted(p for p in files if p.name.endswith("_v1.py"))[:2]
    monkeypatch.setattr(Path, "read_text", _fake_read(edited, removed))
    monkeypatch.setattr(Path, "is_file", _fake_is_file(removed))
    assert set(_generate.differences()) == {edited, removed}


def _fake_read(edited: Path, removed: Path):
    real = Path.read_text

    def read_text(self: Path, *args, **kwargs) -> str:
        text = real(self, *args, **kwargs)
        return text + "# edited by hand\n" if self == edited else text

    return read_text


def _fake_is_file(removed: Path):
    real = Path.is_file

    def is_file(self: Path) -> bool:
        return False if self == removed else real(self)

    return is_file


def test_vector_classes_match_the_env_classes() -> None:
    assert list(VECTOR_ENV_CLASSES) == list(ENV_CLASSES)
    for task, cls in VECTOR_ENV_CLASSES.items():
        assert task == cls.TASK
        assert cls.__module__ == "khepera_gym.vector"
        assert cls.__name__ == ENV_CLASSES[task].__name__.removesuffix("Env") + "VectorEnv"
