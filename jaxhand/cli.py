"""The ``jaxhand`` command line: ``models``, ``demo``, ``synth``, ``track``, ...

Each subcommand lives next to the code it drives and registers itself through a
``register(subparsers)`` function listed in ``_COMMANDS``; ``main(argv)`` is testable in-process.
A :class:`JaxhandError` is printed as one line and exits with status 2.
"""

from __future__ import annotations

import argparse
import importlib
import os
import re
import signal
import sys
import threading
import warnings
from pathlib import Path

from ._errors import InputError, JaxhandError, JaxhandWarning
from ._precision import enable_single_thread_cpu, enable_sync_dispatch, enable_x64

__all__ = ["main"]

# Modules providing `register(subparsers)`; each adds one subcommand with `func` set.
_COMMANDS = [
    "jaxhand.cli_models",
    "jaxhand.cli_track",
    "jaxhand.cli_synth",
    "jaxhand.cli_landmarks",
    "jaxhand.cli_batch",
]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="jaxhand", description="Model-based hand tracking with a JAX core.")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for mod in _COMMANDS:
        importlib.import_module(mod).register(sub)
    return parser


_NUMBERS = re.compile(r"^-[\d.]+(e-?\d+)?(,\s*-?[\d.]+(e-?\d+)?)*$")


def _join_negative_values(argv: list[str]) -> list[str]:
    """``--init -35,-40`` as ``--init=-35,-40``: argparse takes a value that starts with '-' and
    is not a single number for an option, and then reports the flag's value as missing."""
    out: list[str] = []
    for a in argv:
        if out and out[-1].startswith("--") and "=" not in out[-1] and _NUMBERS.match(a):
            out[-1] = f"{out[-1]}={a}"
        else:
            out.append(a)
    return out


def _one_line_warning(message, category, filename, lineno, file=None, line=None):
    print(f"jaxhand: warning: {message}", file=sys.stderr if file is None else file)


def _sigterm_as_interrupt(signum, frame):
    raise KeyboardInterrupt("terminated")


def main(argv: list[str] | None = None) -> int:
    """Run one subcommand; 0 on success, 2 on a usage or input error, 130 when interrupted.

    SIGTERM is handled like Ctrl-C (SIGINT) while the command runs, so both stop a long run the
    same clean way (the command's writers keep every finished frame).
    """
    enable_single_thread_cpu()   # before JAX starts its CPU backend: each small program on one thread
    enable_x64()   # the CLI is a whole program: it may set the process-wide float64 mode jaxhand needs
    enable_sync_dispatch()   # ... and run JAX's small CPU calls on its own thread
    parser = build_parser()
    args = parser.parse_args(_join_negative_values(list(sys.argv[1:] if argv is None else argv)))
    main_thread = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGTERM, _sigterm_as_interrupt) if main_thread else None
    try:
        with warnings.catch_warnings():   # input that is taken but looks wrong: one line each
            warnings.simplefilter("always", JaxhandWarning)
            warnings.showwarning = _one_line_warning
            return int(args.func(args) or 0)
    except JaxhandError as err:
        print(f"jaxhand {args.command}: error: {err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as err:
        why = str(err) if str(err) and str(err) != "terminated" else "the finished frames are kept"
        print(f"jaxhand {args.command}: interrupted; {why}", file=sys.stderr)
        return 130
    finally:
        if main_thread:
            signal.signal(signal.SIGTERM, previous)


def out_dir(path: str | Path, flag: str = "--out") -> Path:
    """Create (if needed) and return an output folder, or say in one line why it cannot be one.

    Raises:
        InputError: the path is a file, lies under a file, or cannot be created or written.
    """
    p = Path(path)
    if p.exists() and not p.is_dir():
        raise InputError(f"{flag} {p}: exists and is a file; give a folder")
    try:
        p.mkdir(parents=True, exist_ok=True)
    except (FileExistsError, NotADirectoryError):
        raise InputError(f"{flag} {p}: lies under a file; give a folder path") from None
    except OSError as err:
        raise InputError(f"{flag} {p}: cannot create the folder ({err.strerror})") from None
    if not os.access(p, os.W_OK | os.X_OK):
        raise InputError(f"{flag} {p}: the folder is not writable")
    return p


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
