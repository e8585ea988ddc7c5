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
    "forging": "signorini.app.commands.forging",
    "optimise-forging": "signorini.app.commands.optimise_forging",
    "sweep": "signorini.app.commands.sweep",
    "run": "signorini.app.commands.run",
}

#: the commands a sweep can run at every point
SWEEPABLE = tuple(n for n in COMMANDS if n != "sweep")


def command(name: str) -> ModuleType:
    """The module of command ``name`` (KeyError for an unknown one)."""
    return importlib.import_module(COMMANDS[name])
