"""The commands of ``signorini``: one module each in :mod:`signorini.app.commands`.

A command module defines ``NAME``, ``add_parser(subparsers)`` and
``execute(args) -> exit code``. The table below names them; :func:`command`
imports one when it is asked for, so that what runs every command (the
``signorini`` entry point, a sweep's tasks) does not import the commands
themselves: the ``sweep`` command runs the others through the entry point.
"""

from __future__ import annotations

import importlib
from types import ModuleType

#: command name -> module, in the order of ``signorini --help``
COMMANDS = {
    "hertz": "signorini.app.commands.hertz",
    "hertz-friction": "signorini.app.commands.hertz_friction",
    "hertz3d": "signorini.app.commands.hertz3d",
    "forging": "signorini.app.commands.forging",
    "forging3d": "signorini.app.commands.forging3d",
    "cylinders": "signorini.app.commands.cylinders",
    "spheres": "signorini.app.commands.spheres",
    "ironing": "signorini.app.commands.ironing",
    "ironing3d": "signorini.app.commands.ironing3d",
    "optimize-forging": "signorini.app.commands.optimize_forging",
    "sweep": "signorini.app.commands.sweep",
    "run": "signorini.app.commands.run",
    "fit": "signorini.app.commands.fit",
    "cache": "signorini.app.commands.cache",
}

#: the commands that write figures and VTU files (the ``signorini`` entry point
#: starts their output helper before anything else: :func:`signorini.post.helper.start`)
OUTPUT_HELPER = ("hertz", "hertz-friction", "hertz3d", "forging", "forging3d", "cylinders", "spheres",
                 "ironing", "ironing3d")

#: the commands a sweep can run at every point (a fit is an optimisation of its own,
#: with its own history and --resume, not one solve per point)
SWEEPABLE = tuple(n for n in COMMANDS if n not in ("sweep", "cache", "fit"))

#: old command names, accepted for one release with a notice: old -> new
RENAMED = {"optimise-forging": "optimize-forging"}


def current_name(name: str) -> tuple[str, str | None]:
    """(the command's name, a deprecation notice or None) for a name as typed."""
    if name in RENAMED:
        new = RENAMED[name]
        return new, (f"the command {name!r} is now {new!r} (one spelling, as in the library's "
                     "optimize); the old name goes in the next release")
    return name, None


def command(name: str) -> ModuleType:
    """The module of command ``name`` (KeyError for an unknown one)."""
    return importlib.import_module(COMMANDS[name])
