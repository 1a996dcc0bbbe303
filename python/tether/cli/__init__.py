"""The ``tether`` command line.

Each subcommand is a module in this package with ``NAME``, ``HELP``, ``add_arguments(parser)`` and
``run(args) -> int``; list it in :data:`COMMANDS` to add it (validate, fit, discover, demo, ...).

:func:`main` is the one top-level handler: no input ever produces a traceback.

* Errors a user can fix (a bad trace, model string, parameter file, output path or argument) print
  ONE line ``tether: error: ...`` to stderr and exit with status 2.
* A missing FMU or a failed simulation or fit prints one line and exits with status 1; so does an
  internal error (a bug: ``tether: internal error: ...``; ``--debug`` shows its traceback).
* A closed stdout (``tether fit ... | head -1``) ends the run quietly with status 141 (as SIGPIPE).
* SIGTERM and SIGINT remove the temporary file of an output being written, print one line and exit
  with 128 + the signal's number (143, 130).
* ``validate`` exits 1 when a trace is outside its tolerance.

The global options --quiet, --verbose and --debug go before or after the subcommand.
"""

from __future__ import annotations

import argparse
import atexit
import os
import signal
import sys
import threading
from typing import Sequence

from .. import atomic as _atomic
from . import console, demo, discover, fit, simulate, sweep, validate

#: subcommand modules, in the order ``tether --help`` lists them
COMMANDS = [simulate, validate, fit, discover, sweep, demo]

USER_ERROR = 2      # bad input: trace, model string, parameter file, output path, arguments
RUN_ERROR = 1       # missing FMU, FMU or engine failure, internal error, validation outside tolerance
BROKEN_PIPE = 128 + 13


class CLIError(Exception):
    """A one-line error raised by a subcommand; ``status`` is the exit status."""

    def __init__(self, message: str, status: int = USER_ERROR):
        super().__init__(message)
        self.status = status


class Terminated(BaseException):
    """Raised by the SIGTERM handler (a BaseException, as KeyboardInterrupt, so cleanup runs)."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum


class _Parser(argparse.ArgumentParser):
    """argparse, but usage errors are one line: ``tether: error: ...``."""

    def error(self, message):  # noqa: D401 - argparse API
        hint = f" (see '{self.prog} --help')"
        console.error(f"{message}{hint}")
        sys.exit(USER_ERROR)


def _escape(text: str) -> str:
    """argparse %-formats help strings: a literal '%' must be '%%'."""
    return text.replace("%", "%%")


def _add_global_options(parser: argparse.ArgumentParser, in_subcommand: bool) -> None:
    # in a subcommand the defaults are SUPPRESS, so that an option given before the subcommand stands
    dflt = {"default": argparse.SUPPRESS} if in_subcommand else {}
    g = parser.add_argument_group("output")
    g.add_argument("-q", "--quiet", dest="verbosity", action="store_const", const=console.QUIET,
                   help="errors only: no progress, warnings or notes on stderr (results still go to stdout)",
                   **({"default": console.NORMAL} if not in_subcommand else dflt))
    g.add_argument("-v", "--verbose", dest="verbosity", action="store_const", const=console.VERBOSE,
                   help="every progress report as its own line (each fit iteration, ...)", **dflt)
    g.add_argument("--debug", dest="verbosity", action="store_const", const=console.DEBUG,
                   help="as --verbose, and an error shows its traceback", **dflt)


def build_parser() -> argparse.ArgumentParser:
    from .. import __version__

    parser = _Parser(prog="tether", description="Simulate, validate, fit and discover models of a braided "
                     "Kevlar tether with the KevlarTether FMU.",
                     epilog="Exit status: 0 done; 1 a failed simulation or fit, a validation outside its "
                            "tolerance, an internal error; 2 bad input. 'tether COMMAND --help' for each.")
    parser.add_argument("--version", action="version", version=f"tether {__version__}")
    _add_global_options(parser, in_subcommand=False)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True
    for mod in COMMANDS:
        p = sub.add_parser(mod.NAME, help=_escape(mod.HELP), description=getattr(mod, "DESCRIPTION", mod.HELP),
                           formatter_class=argparse.RawDescriptionHelpFormatter)
        mod.add_arguments(p)
        _add_global_options(p, in_subcommand=True)
        p.set_defaults(_run=mod.run)
    return parser


_SIGNALS = (signal.SIGTERM, signal.SIGINT)


def _on_signal(signum, frame):  # noqa: ARG001 - signal API
    _atomic.remove_pending()
    raise Terminated(signum)


def _signal_thread(ready: threading.Event) -> None:
    """The process's own command line: wait for SIGTERM/SIGINT in this thread and end the process
    at once, whatever the main thread is doing (a fit inside the engine runs no Python, so a
    Python handler would wait for it: 9 s in a discovery).

    Everything it uses is imported by the main thread before it starts: a daemon thread still
    importing when a short command (``--help``) ends crashed the interpreter's finalization
    (SIGSEGV, docs/cli.md)."""
    ready.set()
    signum = signal.sigwait(set(_SIGNALS))
    with _atomic.LOCK:          # no temporary file is being created or renamed now
        _atomic.remove_pending()
        console.error(f"terminated by {signal.Signals(signum).name}; no partial output was left")
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except (OSError, ValueError):
                pass
        atexit._run_exitfuncs()     # the FMU's extracted copy
        os._exit(128 + signum)


def _install_signal_handlers(own_process: bool) -> dict:
    """SIGTERM and SIGINT remove pending temporary output, then end the run; returns the old handlers.

    In a process of its own (the console script) a thread waits for the signals, blocked in every
    other thread, and this returns once that thread is waiting; called as a library, Python
    handlers raise :class:`Terminated` in the caller."""
    if own_process and hasattr(signal, "pthread_sigmask") and threading.current_thread() is threading.main_thread():
        signal.pthread_sigmask(signal.SIG_BLOCK, _SIGNALS)     # inherited by every thread started later
        ready = threading.Event()
        threading.Thread(target=_signal_thread, args=(ready,), name="tether-signals", daemon=True).start()
        ready.wait()
        return {}
    old = {}
    try:
        for s in _SIGNALS:
            old[s] = signal.signal(s, _on_signal)
    except ValueError:          # not the main thread (tether.cli.main called from a thread)
        pass
    return old


def _silence_stdout() -> None:
    """After a broken pipe: point stdout at /dev/null so that the exit's flush says nothing."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError, AttributeError):
        pass


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; ``argv`` None means the process is ours (the console script,
    ``python -m tether``), so that a signal may end it at once (see :func:`_signal_thread`)."""
    own_process = argv is None
    if own_process:
        from ..blas import limit_process

        limit_process()         # one BLAS thread (docs/speed.md), before anything loads numpy
    argv = list(sys.argv[1:] if argv is None else argv)
    debug = "--debug" in argv
    old_handlers = _install_signal_handlers(own_process)
    try:
        return _main(argv)
    except SystemExit:
        raise
    except BrokenPipeError:
        _silence_stdout()
        return BROKEN_PIPE
    except Terminated as e:
        console.error(f"terminated by {signal.Signals(e.signum).name}; no partial output was left")
        return 128 + e.signum
    except KeyboardInterrupt:
        console.error("interrupted; no partial output was left")
        return 128 + signal.SIGINT
    except Exception as e:  # noqa: BLE001 - the one top-level handler
        return _internal_error(e, debug or console.level() >= console.DEBUG)
    finally:
        for s, h in old_handlers.items():
            signal.signal(s, h)


def _main(argv: list[str]) -> int:
    console.configure(console.NORMAL)          # until the options are read (an earlier call's level)
    args = build_parser().parse_args(argv)
    console.configure(args.verbosity)
    # after the parse: `tether --help` needs none of these (nor numpy)
    from ..fmu import FMUError
    from ..models import ModelError, ParamsError
    from ..run import SimulationError
    from ..traces import TraceError

    try:
        status = args._run(args)
        sys.stdout.flush()
    except (TraceError, ModelError, ParamsError) as e:
        return _fail(e, str(e), USER_ERROR)
    except CLIError as e:
        return _fail(e, str(e), e.status)
    except (FMUError, SimulationError) as e:
        return _fail(e, str(e), RUN_ERROR)
    except BrokenPipeError:
        raise
    except OSError as e:
        # a file the checks let through that the system refused (a full disk, a vanished folder)
        where = f"{e.filename}: " if e.filename else ""
        return _fail(e, f"{where}{e.strerror or e}", RUN_ERROR)
    return int(status or 0)


def _show_traceback(e: BaseException) -> None:
    import traceback

    try:
        traceback.print_exception(type(e), e, e.__traceback__, file=sys.stderr)
    except (BrokenPipeError, ValueError):
        pass


def _internal_error(e: BaseException, debug: bool) -> int:
    if debug:
        _show_traceback(e)
    hint = "" if debug else " (run with --debug to see where)"
    text = " ".join(str(e).split())
    text = text if len(text) <= 300 else text[:297] + "..."
    console.error(f"internal error: {type(e).__name__}: {text}{hint}")
    return RUN_ERROR


def _fail(e: BaseException, message: str, status: int) -> int:
    if console.level() >= console.DEBUG:
        _show_traceback(e)
    console.error(message)
    return status


def warn(message: str) -> None:
    console.warn(message)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
