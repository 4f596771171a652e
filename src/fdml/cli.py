"""The ``fdml`` command line.

Every command is one public library call.  Commands live in
:mod:`fdml.commands`, one module each, and import what they need only when
they run, so ``fdml --help`` stays light (no matplotlib, no scipy).  Errors
print one line on stderr; bad input exits with code 2, other failures with 1.
"""

from __future__ import annotations

import argparse
import importlib
import sys

__all__ = ["main", "build_parser", "EXIT_BAD_INPUT", "EXIT_FAILURE"]

EXIT_BAD_INPUT = 2
EXIT_FAILURE = 1
#: A closed stdout pipe: 128 + SIGPIPE, as a shell reports a process ended by SIGPIPE.
EXIT_CLOSED_PIPE = 141
VERBOSE_HELP = "show warnings and log messages as they happen (before or after the command)"

#: Command modules under fdml.commands, in help order.
COMMANDS = tuple(
    "demo fit compare check simulate response report batch montecarlo diagnose aircraft effects design".split()
)


class _Parser(argparse.ArgumentParser):
    """argparse that reports usage errors as one line with exit code 2."""

    def error(self, message):  # pragma: no cover - exercised through main()
        self.exit(EXIT_BAD_INPUT, f"fdml: error: {message}\n")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every registered command.

    Returns
    -------
    argparse.ArgumentParser
        The ``fdml`` parser, one subcommand per name in :data:`COMMANDS`.
    """
    from . import __version__

    parser = _Parser(
        prog="fdml",
        description="Frequency-domain maximum-likelihood identification "
        "of aircraft short-period dynamics, with unsteady aerodynamics.",
    )
    parser.add_argument("--version", action="version", version=f"fdml {__version__}")
    parser.add_argument("-v", "--verbose", action="store_true", help=VERBOSE_HELP)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    for name in COMMANDS:  # each module's register(sub) adds its parser, named as the module; run(args) runs it
        module = importlib.import_module(f"fdml.commands.{name}")
        module.register(sub)
        sub.choices[name].set_defaults(func=module.run)
    for command in sub.choices.values():  # -v after the command too; absent there, the one before it stands
        command.add_argument("-v", "--verbose", action="store_true", default=argparse.SUPPRESS, help=VERBOSE_HELP)
    return parser


def print_json(obj) -> None:
    """Print ``obj`` as JSON on stdout (inf/nan as strings; :func:`fdml.jsoncodec.dumps`).

    Parameters
    ----------
    obj : object
        Anything :func:`fdml.jsoncodec.dumps` encodes.
    """
    from .jsoncodec import dumps

    sys.stdout.write(dumps(obj, indent=1) + "\n")


def show(args, obj, text) -> None:
    """A command's answer: ``obj`` as JSON with ``--json`` (:func:`print_json`), else ``text`` printed.

    Parameters
    ----------
    args : argparse.Namespace
        The command's arguments (``json``).
    obj : object
        The machine-readable answer.
    text : object
        The answer for a reader.
    """
    if args.json:
        print_json(obj)
    else:
        print(text)


def _closed_pipe() -> int:
    """The reader of stdout went away (``fdml fit ... | head -1``): end quietly.

    The Python documentation's recipe (signal module, "Note on SIGPIPE"):
    point stdout at devnull so that the flush at interpreter exit cannot fail
    again.  The exit code is the shell's for a process ended by SIGPIPE.
    """
    import contextlib
    import os

    with contextlib.suppress(OSError, ValueError):  # no file descriptor behind stdout (an in-process capture)
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    return EXIT_CLOSED_PIPE


def _stdout_closed() -> bool:
    """True when stdout is a pipe whose reader has gone (poll reports an error on it).

    A BrokenPipeError from anywhere else (a worker's pipe) is a failure to report.
    Where poll is unavailable, a BrokenPipeError is taken to be stdout's.
    """
    import select

    if not hasattr(select, "poll"):  # pragma: no cover - Windows
        return True
    try:
        fd = sys.stdout.fileno()
    except (OSError, ValueError, AttributeError):  # an in-process capture: not a pipe
        return False
    poller = select.poll()
    poller.register(fd, select.POLLOUT)
    return any(ev & (select.POLLERR | select.POLLHUP) for _, ev in poller.poll(0))


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """A warning as the command line shows it (with -v): ``fdml: Category: message``, no source path or line."""
    (file or sys.stderr).write(f"fdml: {category.__name__}: {message}\n")


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit code.

    Parameters
    ----------
    argv : list of str, optional
        The arguments after ``fdml`` (default: ``sys.argv[1:]``).

    Returns
    -------
    int
        The exit code: 0 on success, 1 on a failure, 2 on bad input, 130 on
        an interrupt, 141 on a closed output pipe.
    """
    import logging
    import warnings

    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return EXIT_BAD_INPUT
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING, format="fdml: %(message)s")
    from .errors import FdmlError

    try:
        with warnings.catch_warnings():
            if not args.verbose:  # shown with -v only; results keep theirs (fdml.warning_log records past filters)
                warnings.simplefilter("ignore")
            warnings.showwarning = _show_warning  # restored by catch_warnings
            code = int(args.func(args) or 0)
        sys.stdout.flush()  # a closed pipe shows here, not at interpreter exit
        return code
    except BrokenPipeError as exc:
        if _stdout_closed():
            return _closed_pipe()
        sys.stderr.write(f"fdml: internal error: {type(exc).__name__}: {exc}\n")
        return EXIT_FAILURE
    except FdmlError as exc:
        sys.stderr.write(f"fdml: error: {exc}\n")
        return EXIT_BAD_INPUT
    except FileNotFoundError as exc:
        sys.stderr.write(f"fdml: error: {exc.strerror}: {exc.filename}\n")
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:  # pragma: no cover
        sys.stderr.write("fdml: interrupted\n")
        return 130
    except Exception as exc:  # pragma: no cover - a bug: say so in one line, keep the type
        sys.stderr.write(f"fdml: internal error: {type(exc).__name__}: {exc}\n")
        return EXIT_FAILURE


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
