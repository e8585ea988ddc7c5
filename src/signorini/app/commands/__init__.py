"""One module per ``signorini`` command (see :mod:`signorini.app.registry`)."""
