"""Checks on the files the tool reads and writes, before it touches them.

Every problem is said as a short phrase that callers put after the path, so that the message names
the file: ``"is a directory"``, ``"links to /dev/zero, a character device"``, ``"not found"``.

* :func:`input_problem`: a file to read must be a regular file off the kernel's pseudo-filesystems
  (/proc, /sys, /dev): a directory, a device, a FIFO or a socket is said as such, never "not found".
* :func:`output_problem`: a file to write must be a regular file or a new name, in an existing,
  writable folder off the pseudo-filesystems; a device node is never replaced.
* :func:`load_json`: ``json.loads`` with a limit on nesting (:data:`MAX_JSON_DEPTH`), so that a
  hostile file is one clear error (:class:`JSONInputError`) instead of a RecursionError.
"""

from __future__ import annotations

import json
import os
import re
import stat
from pathlib import Path

#: the deepest nesting of objects and arrays any JSON the tool reads may have (ours use 4)
MAX_JSON_DEPTH = 64

#: file systems whose files are the kernel's, not data: never read or written as data files
PSEUDO_FILESYSTEMS = {"proc", "sysfs", "devtmpfs", "devpts", "debugfs", "tracefs", "securityfs", "cgroup",
                      "cgroup2", "pstore", "bpf", "configfs", "fusectl", "mqueue", "efivarfs", "binfmt_misc"}
#: the folders where they are mounted on every Linux system (also where /proc/self/mountinfo is unreadable)
PSEUDO_ROOTS = (Path("/proc"), Path("/sys"), Path("/dev"))


class JSONInputError(ValueError):
    """A JSON text that cannot be read; ``str(e)`` says where and why, for after the file's name."""


class JSONDepthError(JSONInputError):
    """A JSON text nested deeper than :data:`MAX_JSON_DEPTH`; ``lineno``/``colno`` where it passes it."""

    def __init__(self, lineno: int, colno: int, limit: int):
        super().__init__(f"line {lineno}, column {colno}: objects and arrays nested deeper than {limit} levels")
        self.lineno, self.colno, self.limit = lineno, colno, limit


def _kind(mode: int) -> str:
    for test, name in ((stat.S_ISDIR, "a directory"), (stat.S_ISCHR, "a character device"),
                       (stat.S_ISBLK, "a block device"), (stat.S_ISFIFO, "a named pipe (FIFO)"),
                       (stat.S_ISSOCK, "a socket"), (stat.S_ISREG, "a regular file")):
        if test(mode):
            return name
    return "not a regular file"


def _mounts() -> list[tuple[str, str]]:
    """(mount point, file system type) of every mount, from /proc/self/mountinfo; [] if unreadable."""
    try:
        text = Path("/proc/self/mountinfo").read_text()
    except OSError:
        return []
    out = []
    for line in text.splitlines():
        fields = line.split()
        if "-" not in fields:
            continue
        sep = fields.index("-")
        if len(fields) > sep + 1 and len(fields) > 4:
            point = re.sub(r"\\([0-7]{3})", lambda m: chr(int(m.group(1), 8)), fields[4])
            out.append((point, fields[sep + 1]))
    return out


def pseudo_filesystem(path: str | os.PathLike) -> str | None:
    """The pseudo-filesystem ``path`` (resolved) lies on, e.g. "proc", else None."""
    p = Path(os.path.realpath(path))
    for root in PSEUDO_ROOTS:
        if p == root or root in p.parents:
            return {"/proc": "proc", "/sys": "sysfs", "/dev": "devtmpfs"}[str(root)]
    best, kind = "", None
    for point, fstype in _mounts():
        if (str(p) == point or str(p).startswith(point.rstrip("/") + "/")) and len(point) >= len(best):
            best, kind = point, fstype
    return kind if kind in PSEUDO_FILESYSTEMS else None


def _link_note(path: Path, real: Path) -> str:
    return f"links to {real}, " if path.is_symlink() else "is "


def input_problem(path: str | os.PathLike) -> str | None:
    """Why ``path`` cannot be read as a data file, or None if it can."""
    path = Path(path)
    try:
        st = os.stat(path)
    except FileNotFoundError:
        if path.is_symlink():
            return f"is a broken symbolic link (to {os.readlink(path)})"
        return "not found"
    except NotADirectoryError:
        return "not found (a part of the path is not a directory)"
    except PermissionError:
        return "cannot be read (permission denied)"
    except OSError as e:
        return f"cannot be read ({e.strerror})"
    real = Path(os.path.realpath(path))
    if not stat.S_ISREG(st.st_mode):
        return f"{_link_note(path, real)}{_kind(st.st_mode)}, not a regular file"
    fs = pseudo_filesystem(real)
    if fs is not None:
        return f"{_link_note(path, real)}on the kernel's {fs} pseudo-filesystem, not a data file"
    if not os.access(real, os.R_OK):
        return "cannot be read (permission denied)"
    return None


def output_problem(path: str | os.PathLike) -> str | None:
    """Why ``path`` cannot be written (created or replaced) as an output file, or None if it can.

    The file is written where ``path`` leads (a symbolic link is followed), so that is what is
    checked: a regular file or nothing yet, in an existing writable folder off the pseudo-filesystems.
    """
    path = Path(path)
    real = Path(os.path.realpath(path))
    try:
        st = os.stat(real)
    except (FileNotFoundError, NotADirectoryError):     # a new file; its folder is checked below
        st = None
    except OSError as e:
        return f"cannot be checked ({e.strerror})"
    if st is not None and not stat.S_ISREG(st.st_mode):
        what = _kind(st.st_mode)
        if stat.S_ISDIR(st.st_mode):
            return f"{_link_note(path, real)}{what}; expected a file name"
        return f"{_link_note(path, real)}{what}; an output must be a regular file or a new one, and this one is " \
               "never replaced"
    fs = pseudo_filesystem(real)
    if fs is not None:
        return f"{_link_note(path, real)}on the kernel's {fs} pseudo-filesystem; an output must go to a data folder"
    return folder_problem(real.parent)


def folder_problem(folder: str | os.PathLike) -> str | None:
    """Why files cannot be created in ``folder`` (it must exist), or None if they can."""
    folder = Path(folder) if str(folder) else Path(".")
    try:
        st = os.stat(folder)
    except FileNotFoundError:
        return f"folder {folder} does not exist"
    except NotADirectoryError:
        return f"folder {folder} does not exist (a part of the path is not a directory)"
    except OSError as e:
        return f"folder {folder} cannot be checked ({e.strerror})"
    if not stat.S_ISDIR(st.st_mode):
        return f"{folder} is {_kind(st.st_mode)}, not a folder"
    fs = pseudo_filesystem(folder)
    if fs is not None:
        return f"folder {folder} is on the kernel's {fs} pseudo-filesystem; an output must go to a data folder"
    if not os.access(folder, os.W_OK | os.X_OK):
        return f"folder {folder} is not writable"
    return None


def output_dir_problem(path: str | os.PathLike) -> str | None:
    """Why ``path`` cannot be used as an output folder (made if missing, with its parents), or None."""
    path = Path(path)
    real = Path(os.path.realpath(path))
    fs = pseudo_filesystem(real)
    if fs is not None:
        return f"{_link_note(path, real)}on the kernel's {fs} pseudo-filesystem; an output must go to a data folder"
    probe = real
    while not probe.exists():
        if probe.is_symlink() or probe.parent == probe:
            break
        probe = probe.parent
    if probe == real and real.exists():
        if not real.is_dir():
            return f"{_link_note(path, real)}{_kind(os.stat(real).st_mode)}, not a folder"
        return None if os.access(real, os.W_OK | os.X_OK) else "is a folder that is not writable"
    return folder_problem(probe)


_TOKENS = re.compile(r'"(?:[^"\\]|\\.)*"|[\[\]{}]')


def json_depth_check(text: str, limit: int = MAX_JSON_DEPTH) -> None:
    """Raise :class:`JSONDepthError` where ``text`` nests objects/arrays deeper than ``limit``."""
    if text.count("[") + text.count("{") <= limit:
        return
    depth = 0
    for m in _TOKENS.finditer(text):
        c = m.group()
        if c in "[{":
            depth += 1
            if depth > limit:
                pos = m.start()
                line = text.count("\n", 0, pos) + 1
                col = pos - (text.rfind("\n", 0, pos) + 1) + 1
                raise JSONDepthError(line, col, limit)
        elif c in "]}":
            depth -= 1


def load_json(text: str, limit: int = MAX_JSON_DEPTH):
    """``json.loads(text)`` for files from outside: nesting limited, every failure one
    :class:`JSONInputError` (bad syntax with its line and column, too deep, a number Python will
    not convert: an integer of more than 4300 digits)."""
    json_depth_check(text, limit)
    try:
        return json.loads(text)
    except RecursionError:       # a limit set higher than the interpreter's stack
        raise JSONDepthError(1, 1, limit) from None
    except json.JSONDecodeError as e:
        raise JSONInputError(f"line {e.lineno}, column {e.colno}: invalid JSON ({e.msg})") from None
    except ValueError as e:      # Python reads integers of at most 4300 digits
        digits = re.search(r"value has (\d+) digits", str(e))
        raise JSONInputError(f"invalid JSON number (an integer of {digits.group(1) if digits else 'too many'} "
                             "digits; numbers this long are not read)") from None
