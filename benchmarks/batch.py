"""Batch benchmark: ``jaxhand batch`` on 1 and 2 local Dask workers against a loop of single commands.

The jobs are short synthetic sequences (``two_finger_occlusion``, rendered once into a temporary
folder, each with its own pixel-noise seed), tracked with the default settings and ``--no-video``.
Three ways, timed end to end from the shell's point of view, in one run:

- ``loop``: one ``jaxhand track SEQ --out DIR --no-video`` process per job, one after the other,
  the way a user would script it (each process imports jax and compiles the tracker again);
- ``batch_1`` / ``batch_2``: one ``jaxhand batch jobs.csv --out DIR --workers N`` process (cluster
  start, workers that import and compile once, the report).

Each command runs as ``python -m jaxhand.cli`` (what the ``jaxhand`` console script runs) with the
jaxhand this script imports. Reported: wall seconds, jobs/s, frames/s and ``speedup_vs_loop`` (loop wall time over
batch wall time), plus each batch's first-job and later-job compile counts from its report. The
machine's load average is recorded next to the figures: on a shared machine they are noisy.

Run ``python benchmarks/batch.py`` (writes ``benchmarks/results/batch.json``); ``--jobs`` and
``--frames`` size the batch, ``--quick`` is a smoke run (2 jobs of 6 frames, no JSON unless
``--out`` is given).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _common import REPO, RESULTS, environment, format_table, load_average, write_json


def _jaxhand(*args: str) -> float:
    """Seconds one ``jaxhand`` command takes as its own process (output discarded, status checked),
    with the jaxhand this script imported (the one that rendered the inputs)."""
    import jaxhand

    root = str(Path(jaxhand.__file__).resolve().parent.parent)
    env = {**os.environ, "PYTHONPATH": root + os.pathsep + os.environ.get("PYTHONPATH", "")}
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "jaxhand.cli", *args], env=env, cwd=REPO, capture_output=True,
                          text=True)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise SystemExit(f"jaxhand {' '.join(args)} failed ({proc.returncode}):\n{proc.stderr[-2000:]}")
    return wall


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--jobs", type=int, default=6, help="jobs in the batch (default 6)")
    parser.add_argument("--frames", type=int, default=30, help="frames per job (default 30)")
    parser.add_argument("--size", default="160x120", help="frame size WxH (default 160x120)")
    parser.add_argument("--workers", default="1,2", help="worker counts to time (default 1,2)")
    parser.add_argument("--quick", action="store_true", help="smoke run: 2 jobs of 6 frames, no JSON")
    parser.add_argument("--out", help="JSON path (default benchmarks/results/batch.json; none with --quick)")
    args = parser.parse_args(argv)
    if args.quick:
        args.jobs, args.frames = 2, 6
    worker_counts = [int(w) for w in args.workers.split(",")]
    from jaxhand.render import RenderConfig, make_preset, parse_size, write_sequence

    env = environment(extra_packages=("dask", "distributed"))
    with tempfile.TemporaryDirectory(prefix="jaxhand_batch_bench_") as tmp:
        tmp = Path(tmp)
        seq = make_preset("two_finger_occlusion", frames=args.frames, size=parse_size(args.size))
        seqs = []
        for i in range(args.jobs):
            seqs.append(write_sequence(seq, tmp / f"seq{i}", RenderConfig(noise_sigma=4.0, seed=i),
                                       progress=False).parent)
        manifest = tmp / "jobs.csv"
        manifest.write_text("name,inputs,no_video\n*,,true\n" + "".join(f"job{i},{p}\n" for i, p in enumerate(seqs)))
        runs = {}
        t0 = time.perf_counter()
        for i, p in enumerate(seqs):
            _jaxhand("track", str(p), "--out", str(tmp / "loop" / f"job{i}"), "--no-video")
        runs["loop"] = {"wall_s": time.perf_counter() - t0}
        for n in worker_counts:
            out = tmp / f"batch_{n}"
            wall = _jaxhand("batch", str(manifest), "--out", str(out), "--workers", str(n))
            report = json.loads((out / "batch_summary.json").read_text())
            jobs = report["jobs"]
            if any(j["status"] != "done" for j in jobs):
                raise SystemExit(f"batch with {n} workers: not every job finished: {report['totals']}")
            runs[f"batch_{n}"] = {"wall_s": wall, "workers": n,
                                  "jobs_compiling": sum(j["jit_compiles"] > 0 for j in jobs),
                                  "job_wall_s_median": sorted(j["wall_s"] for j in jobs)[len(jobs) // 2]}
    total_frames = args.jobs * args.frames
    for r in runs.values():
        r["jobs_per_s"] = args.jobs / r["wall_s"]
        r["frames_per_s"] = total_frames / r["wall_s"]
        r["speedup_vs_loop"] = runs["loop"]["wall_s"] / r["wall_s"]
    env["load_average_1min_end"] = load_average()
    rows = [[name, r.get("workers", "-"), r["wall_s"], r["jobs_per_s"], r["frames_per_s"], r["speedup_vs_loop"],
             r.get("jobs_compiling", args.jobs)] for name, r in runs.items()]
    print(f"{args.jobs} jobs x {args.frames} frames ({args.size}, two_finger_occlusion); "
          f"load average {env['load_average_1min_start']} -> {env['load_average_1min_end']} on {env['cpu_count']} "
          "cores")
    print(format_table(rows, ["run", "workers", "wall_s", "jobs/s", "frames/s", "speedup_vs_loop",
                              "jobs compiling"]))
    data = {"benchmark": "batch", "environment": env,
            "setup": {"preset": "two_finger_occlusion", "jobs": args.jobs, "frames_per_job": args.frames,
                      "size": args.size, "options": ["--no-video"]},
            "runs": runs,
            "speedup_vs_loop": {str(r["workers"]): r["speedup_vs_loop"] for k, r in runs.items() if k != "loop"}}
    if args.out or not args.quick:
        path = write_json(data, args.out or RESULTS / "batch.json")
        print(f"-> {path.relative_to(REPO) if path.is_relative_to(REPO) else path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
