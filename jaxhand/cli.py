"""The ``jaxhand`` command line: ``models``, ``demo``, ``synth``, ``track``, ...

Each subcommand lives next to the code it drives and registers itself through a
``register(subparsers)`` function listed in ``_COMMANDS``; ``main(argv)`` is testable in-process.
A :class:`JaxhandError` is printed as one line and exits with status 2.
"""

from __future__ import annotations

import argparse
import importlib
import signal
import sys
import threading
from pathlib import Path

from ._errors import JaxhandError

__all__ = ["main"]

# Modules providing `register(subparsers)`; each adds one subcommand with `func` set.
_COMMANDS = [
    "jaxhand.cli_models",
    "jaxhand.cli_track",
    "jaxhand.cli_synth",
]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="jaxhand", description="Model-based hand tracking with a JAX core.")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for mod in _COMMANDS:
        importlib.import_module(mod).register(sub)
    return parser


def _sigterm_as_interrupt(signum, frame):
    raise KeyboardInterrupt("terminated")


def main(argv: list[str] | None = None) -> int:
    """Run one subcommand; 0 on success, 2 on a usage or input error, 130 when interrupted.

    SIGTERM is handled like Ctrl-C (SIGINT) while the command runs, so both stop a long run the
    same clean way (the command's writers keep every finished frame).
    """
    parser = build_parser()
    args = parser.parse_args(argv)
    main_thread = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGTERM, _sigterm_as_interrupt) if main_thread else None
    try:
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


def out_dir(path: str | Path) -> Path:
    """Create (if needed) and return an output folder."""
    p = Path(path)
    p.mkdir(parents=True, exist_ok=True)
    return p


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
