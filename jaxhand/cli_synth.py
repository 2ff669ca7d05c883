"""``jaxhand synth PRESET OUTDIR``: render a synthetic sequence with exact ground truth to a folder."""

from __future__ import annotations

from ._errors import InputError, OutputExistsError

__all__ = ["register"]


def register(sub) -> None:
    from .render import preset_names

    p = sub.add_parser("synth", help="render a synthetic sequence (PNG frames + ground-truth JSON) to a folder",
                       description="Render one of the preset sequences of the thesis and DigitEyes experiments "
                                   f"({', '.join(preset_names())}) into OUTDIR: PNG frames (one folder per "
                                   "camera for several cameras), camera and model files, ground_truth.json "
                                   "and a README.md describing the format.")
    p.add_argument("preset", metavar="PRESET", help=f"one of: {', '.join(preset_names())}")
    p.add_argument("outdir", metavar="OUTDIR", help="output folder")
    p.add_argument("--frames", type=int, default=None, help="number of frames (default: the preset's own)")
    p.add_argument("--size", default="320x240", help="image size WxH (default 320x240)")
    p.add_argument("--noise", type=float, default=0.0, metavar="S", help="Gaussian pixel noise sigma (grey levels)")
    p.add_argument("--blur", type=float, default=0.0, metavar="S", help="Gaussian blur sigma (pixels)")
    p.add_argument("--background", default="black", metavar="B",
                   help="black | constant:V | noise | PATH to an image (default black)")
    p.add_argument("--binary", action="store_true", help="binary silhouettes instead of shaded images")
    p.add_argument("--antialias", type=int, default=1, metavar="K", help="K x K samples per pixel (odd; default 1)")
    p.add_argument("--seed", type=int, default=0, help="seed of the noise texture and the pixel noise")
    p.add_argument("--maps", action="store_true", help="also save link-ID and depth maps (maps_NNNN.npz)")
    p.add_argument("--overwrite", action="store_true", help="replace the frames in a non-empty OUTDIR")
    p.add_argument("--resume", action="store_true",
                   help="continue an interrupted run in OUTDIR (same preset and options) from its next frame")
    p.set_defaults(func=_synth)


def _synth(args) -> int:
    from .render import RenderConfig, make_background, make_preset, parse_size, write_sequence

    try:
        size = parse_size(args.size)
    except InputError as err:
        raise InputError(f"--{err}") from err
    if args.frames is not None and args.frames < 2:
        raise InputError(f"--frames: expected an integer >= 2, got {args.frames}")
    for flag, v in (("--noise", args.noise), ("--blur", args.blur)):
        if not v >= 0:
            raise InputError(f"{flag}: expected a value >= 0, got {v}")
    if args.antialias < 1 or args.antialias % 2 == 0:
        raise InputError(f"--antialias: expected an odd integer >= 1, got {args.antialias}")
    try:  # read the background once up front, so a bad one fails before anything is written
        make_background(args.background, size, args.seed)
    except InputError as err:
        raise InputError(f"--background: {err}") from err
    config = RenderConfig(mode="binary" if args.binary else "shaded", background=args.background,
                          noise_sigma=args.noise, blur_sigma_px=args.blur, antialias=args.antialias, seed=args.seed)
    seq = make_preset(args.preset, frames=args.frames, size=size)
    if args.resume and args.overwrite:
        raise InputError("--resume and --overwrite exclude each other: choose one")
    try:
        path = write_sequence(seq, args.outdir, config, maps=args.maps, overwrite=args.overwrite, resume=args.resume)
    except KeyboardInterrupt:
        raise KeyboardInterrupt(f"the finished frames in {args.outdir} are kept: rerun with --resume to continue"
                                ) from None
    except OutputExistsError as err:
        raise InputError(f"{err} (--resume continues an interrupted run, --overwrite replaces it)") from None
    except InputError as err:
        if "make room and resume" in str(err):
            raise InputError(f"{err} (--resume)") from err
        raise
    print(f"jaxhand synth: {seq.n_frames} frames x {len(seq.cameras)} camera(s) of {seq.name!r} "
          f"({size[0]}x{size[1]}, {config.mode}) -> {path.parent}")
    return 0
