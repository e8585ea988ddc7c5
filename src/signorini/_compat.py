"""The module paths of signorini 0.1, kept for one release.

Version 0.2 moved the flat modules into one package per layer
(``signorini.obstacles`` is now :mod:`signorini.contact.obstacles`, ...).
Importing an old path still works: it gives the new module and raises a
:class:`DeprecationWarning` that names the new path. Names exported by
``signorini`` itself (``sg.solve``, ``sg.Circle``, ...) did not move.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.util
import sys
import types
import warnings

#: old module path -> new module path
MOVED = {
    "signorini.mesh": "signorini.fem.mesh",
    "signorini.kinematics": "signorini.fem.kinematics",
    "signorini.element": "signorini.fem.element",
    "signorini.assembly": "signorini.fem.assembly",
    "signorini.loads": "signorini.fem.loads",
    "signorini.obstacles": "signorini.contact.obstacles",
    "signorini.problem": "signorini.model.problem",
    "signorini.dofs": "signorini.model.dofs",
    "signorini.checks": "signorini.model.checks",
    "signorini.newton": "signorini.algorithms.newton",
    "signorini.solve": "signorini.algorithms.stepping",
    "signorini.solution": "signorini.algorithms.solution",
    "signorini.multilevel": "signorini.algorithms.coarse_to_fine",
    "signorini.uzawa": "signorini.algorithms.uzawa",
    "signorini.gradient": "signorini.design.gradient",
    "signorini.sensitivity.fd": "signorini.design.finite_differences",
    "signorini.optimize": "signorini.design.optimize",
    "signorini.plots": "signorini.post.plots",
    "signorini.cli": "signorini.app.cli",
    "signorini.sweep": "signorini.app.sweep",
    "signorini.runner": "signorini.app.runner",
    "signorini.problemfile": "signorini.app.problemfile",
    "signorini.resources": "signorini.linsolve.memory",
}
#: old modules whose names went to several new ones
SPLIT = {"signorini.io": ("signorini.fem.meshfile", "signorini.post.files")}
#: old modules named like the function the package exports: importing one binds
#: it as that attribute of the package, so it must stay callable as the function
CALLABLE = {"signorini.solve": "solve", "signorini.gradient": "gradient"}


class _CallableModule(types.ModuleType):
    """A deprecated module path that is also the package's function of that name
    (``import signorini.solve`` puts it at ``signorini.solve``): calling it calls
    the function, its attributes are the new module's."""

    def __init__(self, name: str, module: types.ModuleType, function):
        super().__init__(name, module.__doc__)
        object.__setattr__(self, "_module", module)
        object.__setattr__(self, "_function", function)

    def __call__(self, *args, **kwargs):
        return self._function(*args, **kwargs)

    def __getattr__(self, name):
        return getattr(self._module, name)


def _warn(old: str, new: str) -> None:
    warnings.warn(f"the module {old} moved to {new} in signorini 0.2; import it from there "
                  "(the old path goes in the next release)", DeprecationWarning, stacklevel=3)


def _merged(old: str) -> types.ModuleType:
    """A module holding the public names of the modules an old one was split into."""
    mod = types.ModuleType(old, f"Deprecated: see {', '.join(SPLIT[old])}.")
    for new in SPLIT[old]:
        src = importlib.import_module(new)
        for k, v in vars(src).items():
            if not k.startswith("__"):
                setattr(mod, k, v)
    return mod


class _OldPaths(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Resolves an old module path to its new module, with a DeprecationWarning."""

    def __init__(self):
        self._own_spec: dict = {}

    def find_spec(self, name, path=None, target=None):
        if name in MOVED or name in SPLIT:
            return importlib.util.spec_from_loader(name, self)
        return None

    def create_module(self, spec):
        name = spec.name
        if name in SPLIT:
            _warn(name, " and ".join(SPLIT[name]))
            return _merged(name)
        _warn(name, MOVED[name])
        module = importlib.import_module(MOVED[name])
        if name in CALLABLE:
            return _CallableModule(name, module, getattr(module, CALLABLE[name]))
        self._own_spec[module.__name__] = module.__spec__
        return module

    def exec_module(self, module):
        """Nothing to run: the module was imported under its new path. The import
        system has just set its ``__spec__`` to the old path's: give it back its own
        (pickling and reloading go by it)."""
        own = self._own_spec.get(module.__name__)
        if own is not None:
            module.__spec__ = own


def install() -> None:
    """Put the old-path finder on ``sys.meta_path`` (once)."""
    if not any(isinstance(f, _OldPaths) for f in sys.meta_path):
        sys.meta_path.append(_OldPaths())


def module_attribute(name: str):
    """``signorini.<name>`` for an old module name (``sg.io``), or AttributeError."""
    full = f"signorini.{name}"
    if full in MOVED or full in SPLIT:
        return importlib.import_module(full)
    raise AttributeError(f"module 'signorini' has no attribute {name!r}")
