"""The ``tether`` command line.

Each subcommand is a module in this package with ``NAME``, ``HELP``, ``add_arguments(parser)`` and
``run(args) -> int``; list it in :data:`COMMANDS` to add it (validate, fit, discover, demo, ...).

Errors a user can fix (a bad trace, model string, parameter file or argument) print ONE line
``tether: error: ...`` to stderr and exit with status 2; a missing FMU or a failed simulation
prints one line and exits with status 1. No tracebacks for either.
"""

from __future__ import annotations

import argparse
import sys
from typing import Sequence

from . import demo, discover, fit, simulate, sweep, validate

#: subcommand modules, in the order ``tether --help`` lists them
COMMANDS = [simulate, validate, fit, discover, sweep, demo]

USER_ERROR = 2      # bad input: trace, model string, parameter file, arguments
RUN_ERROR = 1       # missing FMU, FMU failure


class CLIError(Exception):
    """A one-line error raised by a subcommand; ``status`` is the exit status."""

    def __init__(self, message: str, status: int = USER_ERROR):
        super().__init__(message)
        self.status = status


class _Parser(argparse.ArgumentParser):
    """argparse, but usage errors are one line: ``tether: error: ...``."""

    def error(self, message):  # noqa: D401 - argparse API
        hint = f" (see '{self.prog} --help')"
        sys.stderr.write(f"tether: error: {message}{hint}\n")
        sys.exit(USER_ERROR)


def build_parser() -> argparse.ArgumentParser:
    from .. import __version__

    parser = _Parser(prog="tether", description="Simulate, validate, fit and discover models of a braided "
                     "Kevlar tether with the KevlarTether FMU.")
    parser.add_argument("--version", action="version", version=f"tether {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True
    for mod in COMMANDS:
        p = sub.add_parser(mod.NAME, help=mod.HELP, description=getattr(mod, "DESCRIPTION", mod.HELP),
                           formatter_class=argparse.RawDescriptionHelpFormatter)
        mod.add_arguments(p)
        p.set_defaults(_run=mod.run)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    from ..fmu import FMUError
    from ..models import ModelError, ParamsError
    from ..run import SimulationError
    from ..traces import TraceError

    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        status = args._run(args)
    except (TraceError, ModelError, ParamsError) as e:
        return _fail(str(e), USER_ERROR)
    except CLIError as e:
        return _fail(str(e), e.status)
    except (FMUError, SimulationError) as e:
        return _fail(str(e), RUN_ERROR)
    except KeyboardInterrupt:
        return _fail("interrupted", 130)
    return int(status or 0)


def _fail(message: str, status: int) -> int:
    line = " ".join(str(message).split("\n"))
    sys.stderr.write(f"tether: error: {line}\n")
    return status


def warn(message: str) -> None:
    sys.stderr.write("tether: warning: " + " ".join(str(message).split("\n")) + "\n")


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
