"""Soak test: a long synthetic sequence tracked through ``track_sequence``; memory, compiles, speed over time.

The two-finger preset's motion (200 frames, played forwards then backwards so the path has no
jump) is repeated for ``--frames`` frames (default 10,000) and tracked by
:func:`jaxhand.track_sequence` with every output but the video (``angles.csv`` row by row,
``results.npz`` checkpoints, ``summary.json``, the angle plot) into a temporary folder. The frames
are streamed from a generator (one small blank image, never stored), and the front end is an
exact-feature oracle of the cycle (0.5 px noise), so the run measures the tracker, the filter and
the writers, not the image analysis.

Every ``--every`` frames it samples the resident set size (``VmRSS`` of ``/proc/self/status``)
and the frames/s of the last window, and counts XLA compilations after the warm-up (there should
be none). It reports the RSS growth per frame after the warm-up (least squares over the samples;
target < 1 KB per frame), the compile count, and the frames/s drift (last quarter over first
quarter of the windows after warm-up); prints a table and writes ``benchmarks/results/soak.json``.

    .venv/bin/python benchmarks/soak.py                 # 10,000 frames (~2-4 min on 2 cores)
    .venv/bin/python benchmarks/soak.py --frames 2000   # a quicker look, no JSON unless --json
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import jax
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))   # this checkout's jaxhand, not an installed one
from _common import RESULTS, environment, format_table, write_json  # noqa: E402

jax.config.update("jax_enable_x64", True)

from jaxhand.io import Frame  # noqa: E402
from jaxhand.render import make_preset  # noqa: E402
from jaxhand.track import AbstractFrontEnd, ExactFrontEnd, FrontEndResult, TrackConfig, track_sequence  # noqa: E402


def rss_bytes() -> int:
    """The process's resident set size (bytes) from /proc/self/status."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) * 1024
    raise RuntimeError("no VmRSS in /proc/self/status")


class StreamedFrames:
    """``n`` frames of one blank image, made on the fly (a frame source for ``track_sequence``)."""

    def __init__(self, n: int, fps: float, size: tuple[int, int]):
        self.n, self.fps = n, fps
        self._image = np.zeros(size[::-1], np.uint8)

    def __len__(self) -> int:
        return self.n

    def __iter__(self):
        for i in range(self.n):
            yield Frame(i, i / self.fps, self._image)


class Sampler:
    """Samples RSS, time and the compile count every ``every`` frames."""

    def __init__(self, every: int):
        self.every, self.rows, self.compiles = every, [], 0
        jax.monitoring.register_event_duration_secs_listener(self._listener)

    def _listener(self, name, duration, **kwargs):
        if name.endswith("backend_compile_duration"):
            self.compiles += 1

    def tick(self, frame: int) -> None:
        if frame % self.every == 0:
            self.rows.append((frame, time.perf_counter(), rss_bytes(), self.compiles))


class CyclicOracle(AbstractFrontEnd):
    """The exact features of ``cycle[frame % len(cycle)]`` (an :class:`ExactFrontEnd` of one
    cycle), calling ``sampler.tick`` every frame."""

    reextracts = False

    def __init__(self, model, cameras, cycle, sampler: Sampler):
        self.exact = ExactFrontEnd(model, cameras, cycle, noise_px=0.5)
        self.period, self.sampler = len(cycle), sampler

    def extract(self, images, q_start, state, frame: int) -> FrontEndResult:
        self.sampler.tick(frame)
        return self.exact.extract(images, q_start, state, frame % self.period)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=10_000, help="frames to track (default 10,000)")
    ap.add_argument("--every", type=int, default=250, help="sample every N frames (default 250)")
    ap.add_argument("--warmup", type=int, default=1000, help="frames left out of the fits (default 1,000)")
    ap.add_argument("--json", action="store_true", help="write results/soak.json for a run of other than 10,000")
    args = ap.parse_args(argv)
    if args.frames < args.warmup + 4 * args.every:
        ap.error("--frames must exceed --warmup by at least four samples")

    seq = make_preset("two_finger_occlusion", frames=200, size=(64, 48))
    cycle = np.concatenate([seq.q, seq.q[::-1]])
    fps = 1.0 / float(seq.times_s[1] - seq.times_s[0])
    sampler = Sampler(args.every)
    frontend = CyclicOracle(seq.model, seq.cameras, cycle, sampler)
    truth = cycle[np.arange(args.frames) % len(cycle)]
    rss_start = rss_bytes()
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as out:
        summary = track_sequence(seq.model, seq.cameras, [StreamedFrames(args.frames, fps, (64, 48))], cycle[0],
                                 out, frontend, config=TrackConfig(), truth=truth, video=False, progress=False)
        rss_end, compiles_end = rss_bytes(), sampler.compiles   # after the summary, its plot and accuracy
        out_bytes = sum(p.stat().st_size for p in Path(out).iterdir())
    wall = time.perf_counter() - t0

    frames, times, rss, compiles = (np.array(c, float) for c in zip(*sampler.rows))
    after = frames >= args.warmup
    slope = float(np.polyfit(frames[after], rss[after], 1)[0])   # bytes per frame
    window_fps = np.diff(frames) / np.diff(times)                 # frames/s of each window
    w_after = frames[1:] > args.warmup
    wf = window_fps[w_after]
    q = max(1, len(wf) // 4)
    first, last = float(np.median(wf[:q])), float(np.median(wf[-q:]))
    compiles_after = int(compiles[-1] - compiles[after][0])   # in the loop, after the warm-up
    result = {
        "frames": args.frames, "sample_every": args.every, "warmup_frames": args.warmup,
        "front_end": "exact-feature oracle of a 400-frame cycle (two_fingers, 0.5 px noise), streamed blank frames",
        "wall_s": wall, "rss_start_mb": rss_start / 2**20, "rss_after_warmup_mb": float(rss[after][0]) / 2**20,
        "rss_last_sample_mb": float(rss[-1]) / 2**20, "rss_after_summary_mb": rss_end / 2**20,
        "rss_growth_bytes_per_frame": slope,
        "compiles_in_loop": int(compiles[-1]), "compiles_after_warmup": compiles_after,
        "compiles_with_summary": compiles_end,
        "frames_per_second_first_quarter": first, "frames_per_second_last_quarter": last,
        "frames_per_second_drift": last / first - 1.0,
        "frames_per_second_end_to_end": summary["frames_per_second_end_to_end"],
        "output_bytes": out_bytes, "lost_frames": summary["lost_frames"],
        "joint_error_deg_mean": summary["accuracy_filtered"]["joint_error_deg"]["mean"],
        "samples": [{"frame": int(f), "t_s": float(t - times[0]), "rss_mb": float(r) / 2**20, "compiles": int(c)}
                    for f, t, r, c in zip(frames, times, rss, compiles)],
        "environment": environment(),
    }
    rows = [[int(f), float(t - times[0]), float(r) / 2**20, int(c), float(v) if k else float("nan")]
            for k, (f, t, r, c, v) in enumerate(zip(frames, times, rss, compiles, np.r_[np.nan, window_fps]))]
    print(format_table(rows[:: max(1, len(rows) // 20)] + ([rows[-1]] if len(rows) % 20 else []),
                       ["frame", "t (s)", "RSS (MB)", "compiles", "frames/s (window)"]))
    print(f"\n{args.frames} frames in {wall:.0f} s; RSS {rss_start / 2**20:.0f} MB at start, "
          f"{rss[after][0] / 2**20:.1f} MB after {args.warmup} frames, {rss[-1] / 2**20:.1f} MB at frame "
          f"{int(frames[-1])} ({rss_end / 2**20:.1f} MB after the summary): growth {slope:.0f} bytes/frame after "
          "warm-up (target < 1024)")
    print(f"compiles: {int(compiles[-1])} in the loop, {compiles_after} after warm-up ({compiles_end} with the "
          f"summary's); frames/s {first:.0f} -> {last:.0f} "
          f"({100 * (last / first - 1):+.1f}%); joint error {result['joint_error_deg_mean']:.2f} deg, "
          f"lost frames {summary['lost_frames']}")
    if args.frames == 10_000 or args.json:
        print(f"wrote {write_json(result, RESULTS / 'soak.json')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
