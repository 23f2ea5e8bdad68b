"""The modules that moved when the package was laid out in layers (release 0.2.0), by old path.

Code written against 0.1.0 imports ``khepera_gym.sb3``, ``khepera_gym.compare.policies`` or
``khepera_gym.catalog``; those paths keep working. An old path resolves to the *same module
object* as its new one (so a monkeypatch through either name hits the same code, and a pickle or
a saved SB3 model that names an old module loads), and the first import of it warns once, with a
:class:`FutureWarning` naming the new path. A submodule of a moved package
(``khepera_gym.sb3.policy``) moves with it.

How: :class:`MovedModuleFinder`, put first in :data:`sys.meta_path` when the package is imported,
answers for the names of :data:`MOVED` and their submodules (no file has such a name any more)
with a loader that imports the new module and returns it. It must come before the ordinary
finders: once ``khepera_gym.sb3`` is the new package, they would find ``vec_env.py`` on its path
and run it a second time as a new module named ``khepera_gym.sb3.vec_env``.

:data:`MOVED` is the one table of moves; ``tests/test_layers.py`` imports every old path through
it and checks that each resolves to its new module.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import importlib.util
import sys
import warnings
from collections.abc import Sequence
from types import CodeType, ModuleType

#: Old module path → new module path.
MOVED: dict[str, str] = {
    "khepera_gym.catalog": "khepera_gym.registry",
    "khepera_gym.versions": "khepera_gym.registry",
    "khepera_gym.face": "khepera_gym.batch_face",
    "khepera_gym.layout": "khepera_gym.observations",
    "khepera_gym.cli_checks": "khepera_gym.tooling.arguments",
    "khepera_gym.provenance": "khepera_gym.tooling.provenance",
    "khepera_gym.compare.stats": "khepera_gym.tooling.stats",
    "khepera_gym.compare.policies": "khepera_gym.learning.policies",
    "khepera_gym.sb3": "khepera_gym.learning.sb3",
    "khepera_gym.rllib": "khepera_gym.learning.rllib",
    "khepera_gym.torchrl": "khepera_gym.learning.torchrl",
    "khepera_gym.benchmarl": "khepera_gym.learning.torchrl.benchmarl",
    "khepera_gym.train": "khepera_gym.learning.train",
    "khepera_gym.hyperparams": "khepera_gym.learning.recipes",
    "khepera_gym.benchmark": "khepera_gym.learning.benchmark",
    "khepera_gym.export": "khepera_gym.robot.export",
    "khepera_gym.calibrate": "khepera_gym.robot.calibrate",
    "khepera_gym.compare": "khepera_gym.analysis.compare",
    "khepera_gym.bench": "khepera_gym.analysis.throughput",
    "khepera_gym.swarm_bench": "khepera_gym.analysis.swarm_throughput",
    "khepera_gym.plot": "khepera_gym.analysis.plots",
    "khepera_gym.record": "khepera_gym.analysis.record",
    "khepera_gym._docgen": "khepera_gym.analysis.docgen",
}


def new_path(old: str) -> str | None:
    """The module path that ``old`` moved to (the longest moved prefix decides), or ``None``."""
    parts = old.split(".")
    for end in range(len(parts), 1, -1):
        moved = MOVED.get(".".join(parts[:end]))
        if moved is not None:
            return ".".join([moved, *parts[end:]])
    return None


class _AliasLoader(importlib.abc.Loader):
    """Loads an old path as the module of its new path (imported once, shared)."""

    def __init__(self, old: str, new: str) -> None:
        self.old = old
        self.new = new

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> ModuleType:
        module = importlib.import_module(self.new)
        self._warn()
        return module

    def _warn(self) -> None:
        warnings.warn(
            f"{self.old} moved to {self.new} in khepera_gym 0.2.0; import it from there "
            "(the old path is the same module and will be removed in a later release)",
            FutureWarning,
            stacklevel=3,
        )

    def exec_module(self, module: ModuleType) -> None:
        """Nothing to run: the new module ran when it was imported."""

    def _target(self) -> importlib.machinery.ModuleSpec:
        spec = importlib.util.find_spec(self.new)
        if spec is None or spec.loader is None:  # pragma: no cover - MOVED names real modules
            raise ImportError(f"{self.old} moved to {self.new}, which cannot be found")
        return spec

    def get_code(self, fullname: str) -> CodeType | None:
        """The new module's code, for ``python -m <old path>`` (runpy runs it as ``__main__``;
        the import of the old path has warned)."""
        self._warn()
        loader = self._target().loader
        get_code = getattr(loader, "get_code", None)
        return None if get_code is None else get_code(self.new)

    def is_package(self, fullname: str) -> bool:
        return self._target().submodule_search_locations is not None


class MovedModuleFinder(importlib.abc.MetaPathFinder):
    """Finds the old paths of :data:`MOVED` (asked after the ordinary finders)."""

    def find_spec(
        self,
        fullname: str,
        path: Sequence[str] | None,
        target: ModuleType | None = None,
    ) -> importlib.machinery.ModuleSpec | None:
        if not fullname.startswith("khepera_gym."):
            return None
        new = new_path(fullname)
        if new is None:
            return None
        loader = _AliasLoader(fullname, new)
        target = loader._target()
        return importlib.machinery.ModuleSpec(
            fullname, loader, is_package=target.submodule_search_locations is not None
        )


def install() -> None:
    """Puts the finder first in :data:`sys.meta_path`, once."""
    if not any(isinstance(finder, MovedModuleFinder) for finder in sys.meta_path):
        sys.meta_path.insert(0, MovedModuleFinder())
