"""The ``graphcal`` command line: thin wrappers around the library.

One module per command (``add_arguments(parser)``, ``run(args) -> int``); the options
several commands share are in :mod:`graphcal.cli.options`. Bad input prints one line
``graphcal: error: …`` and exits with status 2.
"""

from __future__ import annotations

import argparse
import importlib
import os
import signal
import sys
from collections.abc import Sequence
from types import ModuleType

from graphcal import GraphcalError, __version__, first_line, remembering_interrupts

EXIT_BAD_INPUT = 2
#: Exit status after Ctrl-C.
EXIT_INTERRUPTED = 130
#: The commands' modules (in :mod:`graphcal.cli`), in the order ``graphcal --help`` lists them.
COMMANDS = ("simulate", "bench", "import_", "check", "calibrate", "fleet")


def _command_modules() -> list[ModuleType]:
    """The commands' modules, imported when the parser is built: inside :func:`main`, so that
    a Ctrl-C while GTSAM loads is an interrupt like any other."""
    return [importlib.import_module(f"graphcal.cli.{name}") for name in COMMANDS]


class CommandParser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one line, ``graphcal: error: …``, with a
    hint at the command's ``--help`` (not the usage of every option), exit status 2; the
    commands' sub-parsers are of this class too."""

    def parse_args(self, args=None, namespace=None):
        """argparse's, with arguments no command takes named with the command's hint."""
        parsed, unknown = self.parse_known_args(args, namespace)
        if unknown:  # named by the command they were given to, not by ``graphcal``
            command = getattr(parsed, "command", None)
            self.fail(
                f"unrecognized arguments: {' '.join(unknown)}",
                f"{self.prog} {command}" if command else self.prog,
            )
        return parsed

    def error(self, message: str):
        """argparse's usage error, as one line."""
        self.fail(message, self.prog)

    def fail(self, message: str, prog: str):
        """Exit with status 2 after one line: ``message`` and where the options are."""
        what = "commands" if prog == "graphcal" else "options"
        self.exit(EXIT_BAD_INPUT, f"graphcal: error: {message} ({prog} --help for the {what})\n")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``graphcal`` command."""
    parser = CommandParser(
        prog="graphcal",
        description="Wheel-odometry calibration with noise compensation, as GTSAM factor graphs.",
    )
    parser.add_argument("--version", action="version", version=f"graphcal {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for command in _command_modules():
        p = sub.add_parser(
            command.NAME,
            help=command.HELP,
            description=getattr(command, "DESCRIPTION", command.run.__doc__),
        )
        command.add_arguments(p)
        p.set_defaults(func=command.run)
    return parser


def entry() -> int:
    """The ``graphcal`` console script: :func:`main`, then Ctrl-C ignored while the
    interpreter exits (the run is over and its results written; an interrupt there ended
    the process by the signal, exit -2, with a traceback from an exit handler). An
    interrupted run ends at once (``os._exit``) once it has said so: an exit handler that
    joins a worker pool's threads hung for good under load (issue 44)."""
    status = main()
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if status == EXIT_INTERRUPTED:  # said and cleaned up: no exit handler may wait on a worker
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(status)
    return status


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``graphcal`` console script; returns the exit status. A Ctrl-C is
    remembered as well as raised (:func:`graphcal.remembering_interrupts`): one dropped
    inside a fork's callback or a finalizer still ends the run before it writes."""
    try:
        with remembering_interrupts():
            args = build_parser().parse_args(argv)
            return args.func(args)
    except GraphcalError as exc:
        print(f"graphcal: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt as exc:  # a note, if any, says what was kept and how to go on
        note = first_line(str(exc))
        print(f"graphcal: interrupted{f'; {note}' if note else ''}", file=sys.stderr)
        return EXIT_INTERRUPTED
    except ImportError as exc:  # an extension module's import interrupted
        if not isinstance(exc.__cause__, KeyboardInterrupt):
            raise
        print("graphcal: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except BrokenPipeError:  # e.g. `graphcal check LOG | head`: the reader left, not an error
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 0
