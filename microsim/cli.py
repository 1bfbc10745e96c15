"""The command line: ``microsim <command> ...``.

Exit statuses: 0 success, 1 internal failure, 2 bad input (one line on stderr that starts
with ``error:`` and names the key or flag and what is allowed). Each command lives in
``microsim/commands/<name>.py`` with ``register(subparsers)``; heavy modules (Embree,
PyVista, matplotlib) are imported inside the command's ``run``, so ``microsim --help``
and ``microsim check`` start fast.
"""

from __future__ import annotations

import argparse
import atexit
import importlib
import os
import sys
import warnings
from collections.abc import Sequence
from types import ModuleType
from typing import Any

from microsim.errors import InputError, InputWarning
from microsim.version import __version__

NAMES = ("check", "models", "generate", "measure", "view", "simulate", "compare", "fit", "sh",
         "export", "render", "bench", "batch", "demo", "wavelets", "eval")
"""The commands, in the order ``--help`` lists them: each the module
``microsim.commands.<name>``."""


def commands() -> dict[str, ModuleType]:
    """The command modules by name (``NAMES``), imported on the first call: ``main`` imports
    them inside its guard, so a Ctrl-C while they load is the one line of any other, and
    importing this module loads nothing heavy (numpy among them)."""
    return {name: importlib.import_module(f"microsim.commands.{name}") for name in NAMES}


def build_parser() -> argparse.ArgumentParser:
    """The ``microsim`` parser with every command registered."""
    from microsim.commands.common import Parser

    parser = Parser(
        prog="microsim",
        description="Microgeometry simulator: builds explicit microsurfaces, ray traces them "
                    "with Embree as a virtual goniophotometer, and writes BRDF tables with "
                    "error bars. Angles on the command line are in degrees.",
    )
    parser.add_argument("--version", action="version", version=f"microsim {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=Parser)
    for command in commands().values():
        command.register(sub)
    return parser


def one_line(message: str) -> str:
    """``message`` with every character that is not printable (a newline or control
    character from a user's file name or value) escaped, so it stays one line."""
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in message)


def _show_warning(message: Warning | str, category: type[Warning], filename: str,
                  lineno: int, file: Any = None, line: str | None = None) -> None:
    """``warnings.showwarning`` of the CLI: every warning is one ``warning:`` line on
    stderr; an ``InputWarning`` says it all, another (numpy's, scipy's, a library's) names
    its category and where it was raised, without the source line Python adds."""
    if issubclass(category, InputWarning):
        print(f"warning: {one_line(str(message))}", file=sys.stderr)
    else:
        where = f"{os.path.basename(filename)}:{lineno}"
        print(f"warning: {category.__name__}: {one_line(str(message))} ({where})",
              file=sys.stderr)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; return the exit status.

    Parameters
    ----------
    argv : sequence of str or None
        Arguments without the program name (None: ``sys.argv[1:]``).

    Returns
    -------
    int
        0 success, 1 internal failure, 2 bad input.
    """
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("always", InputWarning)
            warnings.showwarning = _show_warning
            parser = build_parser()
            args = parser.parse_args(argv)
            if args.command is None:
                raise InputError("a command is required, one of: " + ", ".join(NAMES)
                                 + " (microsim --help describes them)")
            from microsim.effort import note, scaled
            from microsim.memory import flag_limit

            quick = note()
            if quick is not None:
                print(f"warning: {quick}", file=sys.stderr)
                if getattr(args, "spp", None) is not None:
                    args.spp = scaled(args.spp, least=2)  # 1 spp leaves the noise unknown
            with flag_limit(getattr(args, "memory_limit", None)):
                return int(args.func(args) or 0)
    except InputError as exc:
        print(f"error: {one_line(str(exc))}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("error: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        return 0
    except OSError as exc:  # the device or stream the user chose (a full disk, /dev/full)
        where = exc.filename or "output"
        print(f"error: {one_line(str(where))}: {exc.strerror or exc}", file=sys.stderr)
        return 2


def run() -> None:
    """The ``microsim`` command: ``main``, then the end of the process without the
    interpreter's teardown of its modules (after a simulation, unloading the compiled
    kernel takes about 0.15 s, longer than many a command's work). Every command has
    written, closed and renamed its files, and left its clusters, by the time ``main``
    returns; the exit handlers still run (Embree's device release); the standard
    streams are flushed."""
    code = main()
    try:
        sys.stdout.flush()
        sys.stderr.flush()
    except BrokenPipeError:
        pass
    except OSError as exc:  # buffered output that did not fit (stdout to a full device)
        os.write(2, f"error: output: {exc.strerror or exc}\n".encode())
        code = 2
    atexit._run_exitfuncs()  # the handlers the normal exit would call first
    os._exit(code)


if __name__ == "__main__":
    run()
