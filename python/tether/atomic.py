"""Atomic output: every file the project writes appears whole or not at all.

Each writer writes a temporary file in the target's directory, gives it the mode a plain open()
would (mkstemp makes 0600), and renames it over the target; on any error the temporary file is
removed and the target is left as it was.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import Callable, TextIO


def _default_mode(path: str) -> None:
    mask = os.umask(0)
    os.umask(mask)
    os.chmod(path, 0o666 & ~mask)


def replace_with(path: str | os.PathLike, write: Callable[[str], None], suffix: str = ".tmp") -> None:
    """Call ``write(tmp_path)`` to fill a temporary file, then rename it over ``path``."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=suffix, dir=str(path.parent))
    os.close(fd)
    try:
        write(tmp)
        _default_mode(tmp)
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


def write_with(path: str | os.PathLike, fill: Callable[[TextIO], None]) -> None:
    """Write a text file through ``fill(file)``, atomically, flushed to disk before the rename."""

    def write(tmp: str) -> None:
        with open(tmp, "w", encoding="utf-8", newline="\n") as f:
            fill(f)
            f.flush()
            os.fsync(f.fileno())

    replace_with(path, write)


def write_text(path: str | os.PathLike, text: str) -> None:
    write_with(path, lambda f: f.write(text))
