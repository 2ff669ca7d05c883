"""``jaxhand models`` (list built-ins, export one to a file) and ``jaxhand sketch`` (draw poses)."""

from __future__ import annotations

import numpy as np

from ._errors import InputError
from .model import add_palm, builtin_model, builtin_names, get_model, mirror_model, save_model
from .model.builtin import BUILTIN_DESCRIPTIONS

__all__ = ["register", "sketch_poses"]


def register(sub) -> None:
    p = sub.add_parser("models", help="list the built-in models with their DOF and joint names")
    p.add_argument("name", nargs="?", help="show one model in full")
    p.add_argument("--export", metavar="FILE", help="write the model to FILE (.toml or .json)")
    p.add_argument("--mirror", action="store_true",
                   help="use the model's mirror image (a left hand from a right one and back)")
    p.add_argument("--palm", action="store_true",
                   help="add palm and forearm occluder pills laid out from the fingers' bases (for a learned "
                        "foreground, which sees them; see jaxhand.model.add_palm)")
    p.add_argument("--forearm-mm", type=float, default=100.0,
                   help="forearm length with --palm (default 100, as the dev set's hand; it is rigid with the "
                        "palm, so keep it short where the wrist bends)")
    p.set_defaults(func=_models)
    s = sub.add_parser("sketch", help="draw a model at its default and a few random poses to PNG")
    s.add_argument("--model", default="hand21", help="built-in name or model file")
    s.add_argument("--out", default="sketch_out", help="output folder")
    s.add_argument("--poses", type=int, default=3, help="random poses besides the default")
    s.set_defaults(func=_sketch)


def _models(args) -> int:
    if args.name is None:
        for name in builtin_names():
            m = builtin_model(name)
            hand = f", {m.handedness} hand" if m.handedness != "none" else ""
            print(f"{name:12s} {m.dof:3d} DOF ({m.n_q} q entries, {m.base_kind} base, {m.n_links} links, "
                  f"{m.n_tips} tips{hand})  {BUILTIN_DESCRIPTIONS[name]}")
            print(f"{'':12s} joints: {', '.join(m.q_names)}")
        return 0
    m = get_model(args.name)
    if args.mirror:
        m = mirror_model(m)
    if args.palm:
        m = add_palm(m, forearm_mm=args.forearm_mm)
    lo, hi, q0 = (np.asarray(a) for a in (m.q_lower, m.q_upper, m.q_default))
    hand = f", {m.handedness} hand" if m.handedness != "none" else ""
    occ = f", {m.n_occluders} occluders ({', '.join(m.occluder_names)})" if m.n_occluders else ""
    print(f"{m.name}: {m.dof} DOF, {m.n_q} q entries, {m.base_kind} base, {m.n_links} links{occ}{hand}")
    for i, n in enumerate(m.q_names):
        conv, unit = (np.degrees, "deg") if m.is_angle[i] else (float, "mm" if m.q_kinds[i] == "length" else "")
        print(f"  {n:16s} [{conv(lo[i]):8.2f}, {conv(hi[i]):8.2f}] default {conv(q0[i]):8.2f} {unit}")
    if args.export:
        try:
            print(f"wrote {save_model(m, args.export)}")
        except OSError as err:
            raise InputError(f"--export {args.export}: cannot write ({err.strerror}); give a writable path") from None
    return 0


def sketch_poses(model_name: str, out, n_random: int = 3, seed: int = 0) -> list:
    """Draw ``model_name`` at its default pose and ``n_random`` random poses; returns the PNG paths."""
    import cv2

    from .camera import Orthographic
    from .cli import out_dir
    from .kinematics import forward, random_q
    from .viz import sketch_model

    m = get_model(model_name)
    out = out_dir(out)
    rng = np.random.default_rng(seed)
    poses = [np.asarray(m.q_default)] + list(random_q(m, rng, n_random, margin=0.1))
    ends = [np.concatenate([forward(m, q).link_start, forward(m, q).link_end]) for q in poses]
    cam = Orthographic.fit(np.concatenate(ends), size=(320, 240))
    paths = []
    for k, q in enumerate(poses):
        path = out / f"{m.name}_{'default' if k == 0 else f'random{k}'}.png"
        cv2.imwrite(str(path), sketch_model(m, cam, q))
        paths.append(path)
    return paths


def _sketch(args) -> int:
    if args.poses < 0:
        raise InputError(f"--poses: expected a count >= 0, got {args.poses}")
    for p in sketch_poses(args.model, args.out, args.poses):
        print(p)
    return 0
