"""Output files written whole or not at all."""

from __future__ import annotations

import contextlib
import os
from pathlib import Path


@contextlib.contextmanager
def atomic(path):
    """Write a file atomically: yields a temporary path beside ``path`` (same
    directory and extension, so writers that go by the extension work), renamed
    onto ``path`` when the block ends (a reader sees the old file or the whole
    new one, never a part: an interrupted run leaves no half-written output);
    removed if the block raises."""
    path = Path(path)
    tmp = path.with_name(f".{path.stem}.{os.getpid()}.partial{path.suffix}")
    try:
        yield tmp
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise
