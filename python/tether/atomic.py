"""Atomic output: every file the project writes appears whole or not at all.

Each writer writes a temporary file in the target's directory, gives it the mode a plain open()
would, and renames it over the target; on any error the temporary file is removed and the target is
left as it was.

A temporary file is named ``.NAME.PID.RANDOM.tether-tmp`` beside its target, and its name is
registered (:data:`PENDING`) before the file is created, so that :func:`remove_pending` (called by
the command line's SIGTERM/SIGINT handling, in a handler or in a thread of its own: :data:`LOCK`)
removes every temporary file the process has open at any instant. SIGKILL cannot be caught: a killed run may leave one behind; the next write to the same
folder removes those whose process is gone (:func:`remove_stale`).
"""

from __future__ import annotations

import os
import re
import secrets
import threading
from pathlib import Path
from typing import Callable, TextIO

#: the ending of every temporary file this module makes
TMP_SUFFIX = ".tether-tmp"
#: temporary files of this process not yet renamed or removed
PENDING: set[str] = set()
#: held while a temporary file is created or renamed, and by :func:`remove_pending` from another
#: thread (re-entrant: a signal handler in the main thread may run inside those sections)
LOCK = threading.RLock()

_TMP_NAME = re.compile(r"^\..*\.(\d+)\.[0-9a-f]{8}" + re.escape(TMP_SUFFIX) + r"$")


def _default_mode(path: str) -> None:
    mask = os.umask(0)
    os.umask(mask)
    os.chmod(path, 0o666 & ~mask)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def remove_stale(folder: str | os.PathLike) -> list[Path]:
    """Remove this module's temporary files in ``folder`` whose process no longer runs."""
    removed = []
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return removed
    for e in entries:
        m = _TMP_NAME.match(e.name)
        if m and int(m.group(1)) != os.getpid() and not _alive(int(m.group(1))):
            try:
                os.unlink(e.path)
                removed.append(Path(e.path))
            except OSError:
                pass
    return removed


def remove_pending() -> None:
    """Remove every temporary file of this process (safe to call from a signal handler)."""
    with LOCK:
        for tmp in list(PENDING):
            try:
                os.unlink(tmp)
            except OSError:
                pass
            PENDING.discard(tmp)


def _create_temp(path: Path) -> str:
    """Create (exclusively) and register a new temporary file for ``path``; return its name."""
    while True:
        tmp = str(path.parent / f".{path.name}.{os.getpid()}.{secrets.token_hex(4)}{TMP_SUFFIX}")
        with LOCK:
            PENDING.add(tmp)              # registered before it exists: a signal never misses it
            try:
                os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600))
                return tmp
            except FileExistsError:
                PENDING.discard(tmp)
            except BaseException:
                PENDING.discard(tmp)
                raise


def replace_with(path: str | os.PathLike, write: Callable[[str], None]) -> None:
    """Call ``write(tmp_path)`` to fill a temporary file, then rename it over ``path``."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    remove_stale(path.parent)
    tmp = _create_temp(path)
    try:
        write(tmp)
        _default_mode(tmp)
        with LOCK:
            os.replace(tmp, path)
            PENDING.discard(tmp)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        PENDING.discard(tmp)
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
