"""``jaxhand demo``: draw the built-in full hand at a few poses (until the tracker lands)."""

from __future__ import annotations

__all__ = ["register"]


def register(sub) -> None:
    p = sub.add_parser("demo", help="run the built-in demonstration and say where its results are")
    p.add_argument("--out", default="demo_out", help="output folder")
    p.set_defaults(func=_demo)


def _demo(args) -> int:
    from .cli_models import sketch_poses

    paths = sketch_poses("hand21", args.out, 3)
    print("jaxhand demo: the 21-DOF hand at its default pose and three random poses within limits:")
    for p in paths:
        print(f"  {p}")
    return 0
