"""What the command line says on stderr, and how much: --quiet, --verbose, --debug, progress.

Results go to stdout; everything else (progress, warnings, errors) to stderr. The level is set once
by :func:`configure` from the global options:

* ``--quiet`` (0): errors only: no progress, no warnings, no notes;
* default (1): warnings, notes, and progress: a bar with the time left when stderr is a terminal,
  else plain lines: each stage as it starts, its first report, then one at most every
  :data:`PLAIN_INTERVAL` seconds;
* ``--verbose`` (2): also every progress report (each fit iteration, ...) as its own line;
* ``--debug`` (3): as --verbose, and an error shows its traceback.

The bar is tqdm's, imported only when a bar is shown.
"""

from __future__ import annotations

import os
import sys
import threading
import time

QUIET, NORMAL, VERBOSE, DEBUG = 0, 1, 2, 3

#: seconds between two plain progress lines of the same task (no terminal)
PLAIN_INTERVAL = 10.0

_level = NORMAL
_bars_shown = 0         # bars on the terminal now: an error line starts below them


def configure(level: int) -> None:
    global _level
    _level = int(level)


def level() -> int:
    return _level


def _one_line(message: str) -> str:
    return " ".join(str(message).split("\n"))


def _write(text: str) -> None:
    try:
        sys.stderr.write(text)
        sys.stderr.flush()
    except (BrokenPipeError, ValueError):     # stderr closed: nothing to tell it
        pass


def note(message: str) -> None:
    """A line for the user on stderr (not with --quiet)."""
    if _level >= NORMAL:
        _write(_one_line(message) + "\n")


def warn(message: str) -> None:
    if _level >= NORMAL:
        _write("tether: warning: " + _one_line(message) + "\n")


def error(message: str) -> None:
    """The one line of an error (always shown)."""
    _write(("\n" if _bars_shown else "") + "tether: error: " + _one_line(message) + "\n")


def _clock(seconds: float) -> str:
    seconds = max(0, int(round(seconds)))
    m, s = divmod(seconds, 60)
    h, m = divmod(m, 60)
    return f"{h:d}:{m:02d}:{s:02d}" if h else f"{m:02d}:{s:02d}"


def _use_bar() -> bool:
    try:
        return sys.stderr.isatty()
    except (AttributeError, ValueError):
        return False


class Progress:
    """The progress of one long task: ``with Progress("fit", total) as p: p.update(done, status)``.

    ``done`` runs from 0 to ``total`` (any unit); the time left is estimated from the rate so far,
    or, with ``deadline=True``, is the time to ``total`` seconds (a budget: "at most"). ``line()``
    prints a message above the bar (or as a plain line).
    """

    def __init__(self, name: str, total: float, *, unit: str = "", deadline: bool = False):
        self.name, self.total, self.unit, self.deadline = name, float(total), unit, deadline
        self.t0 = time.perf_counter()
        self.done = 0.0
        self.status = ""
        self._last_plain = -PLAIN_INTERVAL
        self._fresh = False          # print the next report in plain mode whatever the interval
        self._lock = threading.Lock()
        self._bar = None
        self._ticker = None
        self._stop = threading.Event()
        if _level >= NORMAL and _use_bar():
            self._bar = self._make_bar()
        if self._bar is not None:
            global _bars_shown
            _bars_shown += 1
        if deadline and _level >= NORMAL:
            self._ticker = threading.Thread(target=self._tick, name="tether-progress", daemon=True)
            self._ticker.start()

    def _make_bar(self):
        try:
            from tqdm import tqdm
        except ImportError:          # a plain line instead of a bar
            return None
        left = "at most {remaining} left" if self.deadline else "{remaining} left"
        fmt = "{desc}: {percentage:3.0f}%|{bar}| {elapsed} elapsed, " + left + "{postfix}"
        try:
            size = os.get_terminal_size(sys.stderr.fileno())
        except (OSError, ValueError, AttributeError):
            size = os.terminal_size((0, 0))
        # a terminal that reports no size (a pseudo-terminal nobody sized) would hide the bar
        shape = {"dynamic_ncols": True} if size.columns > 0 and size.lines > 0 else {"ncols": 80, "nrows": 24}
        return tqdm(total=self.total, desc=self.name, file=sys.stderr, bar_format=fmt, leave=False,
                    mininterval=0.2, smoothing=0.1, **shape)

    # -- updates -------------------------------------------------------------------------------
    def elapsed(self) -> float:
        return time.perf_counter() - self.t0

    def update(self, done: float, status: str = "") -> None:
        """Set the work done so far (never goes back) and a short status."""
        with self._lock:
            done = min(max(float(done), self.done), self.total)
            step, self.done = done - self.done, done
            if status:
                self.status = status
            if self._bar is not None:
                if status:
                    self._bar.set_postfix_str(status, refresh=False)
                self._bar.update(step)
                return
        if status and _level >= VERBOSE:
            _write(f"  {status}\n")
        elif _level >= NORMAL and (self._fresh or self.elapsed() - self._last_plain >= PLAIN_INTERVAL):
            self._plain()

    def line(self, message: str) -> None:
        """A message line: above the bar, or plain (not with --quiet)."""
        if _level < NORMAL:
            return
        with self._lock:
            if self._bar is not None:
                self._bar.write(_one_line(message), file=sys.stderr)
                return
        _write(_one_line(message) + "\n")
        self._last_plain = self.elapsed()
        self._fresh = not self.deadline     # a stage began: say how the next report stands (once)

    def _left(self) -> float | None:
        if self.deadline:
            return max(self.total - self.elapsed(), 0.0)
        if self.done <= 0:
            return None
        return self.elapsed() * (self.total - self.done) / self.done

    def _plain(self) -> None:
        self._last_plain = self.elapsed()
        self._fresh = False
        left = self._left()
        when = f"{_clock(self.elapsed())} elapsed" + (
            "" if left is None else f", {'at most ' if self.deadline else 'about '}{_clock(left)} left")
        pct = 100.0 * self.done / self.total if self.total > 0 else 100.0
        status = f" ({self.status})" if self.status else ""
        _write(f"{self.name}: {pct:3.0f} %{status}, {when}\n")

    def _tick(self) -> None:
        while not self._stop.wait(1.0):
            self.update(self.elapsed())

    def close(self) -> None:
        self._stop.set()
        if self._ticker is not None:
            self._ticker.join()
        with self._lock:
            if self._bar is not None:
                global _bars_shown
                self._bar.close()
                self._bar = None
                _bars_shown -= 1

    def __enter__(self) -> "Progress":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
