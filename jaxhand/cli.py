"""The ``jaxhand`` command line: ``models``, ``demo``, ``synth``, ``track``, ...

Each subcommand lives next to the code it drives and registers itself through a
``register(subparsers)`` function listed in ``_COMMANDS``; ``main(argv)`` is testable in-process.
A :class:`JaxhandError` is printed as one line and exits with status 2.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from pathlib import Path

from ._errors import JaxhandError

__all__ = ["main"]

# Modules providing `register(subparsers)`; each adds one subcommand with `func` set.
_COMMANDS = [
    "jaxhand.cli_models",
    "jaxhand.cli_track",
    "jaxhand.cli_synth",
    "jaxhand.cli_batch",
]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="jaxhand", description="Model-based hand tracking with a JAX core.")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for mod in _COMMANDS:
        importlib.import_module(mod).register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except JaxhandError as err:
        print(f"jaxhand {args.command}: error: {err}", file=sys.stderr)
        return 2


def out_dir(path: str | Path) -> Path:
    """Create (if needed) and return an output folder."""
    p = Path(path)
    p.mkdir(parents=True, exist_ok=True)
    return p


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
