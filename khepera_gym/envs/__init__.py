"""Single-world Gymnasium environments over the Rust core, and heuristic policies that solve them.

One module per task family (``nav.py`` holds :class:`NavEnv` and :class:`AvoidEnv`), each with its
env classes (subclasses of :class:`KheperaEnv`, :mod:`khepera_gym.envs.base`, whose ``TASK`` is
the Rust task's name and whose docstring is the task's manual) and its heuristics: thin wrappers
of the paper's controllers in :mod:`khepera_gym.baselines` (computed in Rust), such as
:func:`nav_heuristic`. :data:`ENV_CLASSES` holds every env class by task.

This package imports its modules by listing itself and exports what each one exports, so a new
task is a new module here and nothing else; registration with Gymnasium comes from the task list
the Rust core exports.
"""

import importlib
import pkgutil

from khepera_gym.config import ACTION_TYPES
from khepera_gym.envs.base import ENV_CLASSES, KheperaEnv

__all__ = ["ACTION_TYPES", "ENV_CLASSES", "KheperaEnv"]
for _info in pkgutil.iter_modules(__path__):
    if _info.name != "base" and not _info.name.startswith("_"):
        _module = importlib.import_module(f"{__name__}.{_info.name}")
        globals().update({name: getattr(_module, name) for name in _module.__all__})
        __all__ += _module.__all__
__all__.sort()

# The manuals' examples live in the task modules: doctest.testmod(khepera_gym.envs) runs them.
__test__ = {cls.__name__: cls for cls in ENV_CLASSES.values()}
