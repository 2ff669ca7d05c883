"""Helpers shared by benchmark scripts: timing, the environment record, tables and JSON.

- :func:`median_seconds`: median time of a call after a warm-up, every call blocked on
  (``jax.block_until_ready``), repeated samples;
- :func:`first_call_seconds`: the time of a first call (trace + compile + run);
- :func:`environment`: what produced the numbers (CPU, core count, device, library versions, commit,
  load average), never machine paths or user names;
- :func:`format_table` and :func:`write_json` (into ``benchmarks/results/``);
- :func:`add_runtime_option` / :func:`apply_runtime`: ``--cli-runtime``, JAX run as the CLI runs it.
"""

from __future__ import annotations

import gc
import importlib.metadata
import json
import os
import platform
import statistics
import subprocess
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import jax
import numpy as np

import jaxhand

jaxhand.enable_x64()   # every benchmark imports this module before building anything

__all__ = ["REPO", "RESULTS", "add_runtime_option", "apply_runtime", "block", "time_call", "median_seconds",
           "first_call_seconds", "environment", "load_average", "format_table", "write_json"]

REPO = Path(__file__).resolve().parent.parent
RESULTS = REPO / "benchmarks" / "results"


def add_runtime_option(parser) -> None:
    """``--cli-runtime``: run JAX as the ``jaxhand`` CLI does (one thread per CPU computation,
    synchronous dispatch) instead of JAX's defaults."""
    parser.add_argument("--cli-runtime", action="store_true",
                        help="JAX as the CLI runs it: jaxhand.enable_single_thread_cpu() and enable_sync_dispatch()")


def apply_runtime(args) -> None:
    """Apply ``--cli-runtime`` (call it before the first JAX computation); :func:`environment`
    records what is in force (``xla_flags``, ``async_dispatch``)."""
    if args.cli_runtime:
        jaxhand.enable_single_thread_cpu()
        jaxhand.enable_sync_dispatch()


def block(x):
    """Wait for every JAX array in ``x`` (any pytree; other leaves are left alone)."""
    return jax.block_until_ready(x)


def time_call(fn: Callable[[], object]) -> tuple[float, object]:
    """Seconds one blocked call of ``fn`` takes, and its result."""
    t0 = time.perf_counter()
    out = block(fn())
    return time.perf_counter() - t0, out


def median_seconds(fn: Callable[[], object], *, repeats: int = 7, min_sample_s: float = 0.05,
                   max_total_s: float = 10.0, warmup: int = 1) -> float:
    """Median over samples of the seconds per call of ``fn`` (each call blocked on).

    ``warmup`` untimed calls first (compilation, caches); each sample then runs ``fn`` often enough
    to last ``min_sample_s``, and ``repeats`` samples are taken (fewer, at least 3, where they
    would take longer than ``max_total_s``). The garbage collector is paused while sampling.
    """
    for _ in range(warmup):
        block(fn())
    t, _ = time_call(fn)
    n = max(1, int(np.ceil(min_sample_s / max(t, 1e-9))))
    k = max(3, min(repeats, int(max_total_s / max(n * t, 1e-9))))
    samples = []
    gc.collect()
    gc.disable()
    try:
        for _ in range(k):
            t0 = time.perf_counter()
            for _ in range(n):
                block(fn())
            samples.append((time.perf_counter() - t0) / n)
    finally:
        gc.enable()
    return statistics.median(samples)


def first_call_seconds(fn: Callable[[], object]) -> float:
    """Seconds of the first (compiling) call of ``fn``."""
    return time_call(fn)[0]


def load_average() -> float | None:
    """The 1-minute load average (None where the OS has none): a busy machine shifts timings."""
    return round(os.getloadavg()[0], 2) if hasattr(os, "getloadavg") else None


def _cpu_name() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _git(*args: str) -> str | None:
    try:
        out = subprocess.run(["git", *args], cwd=REPO, capture_output=True, text=True, timeout=10, check=True)
    except (OSError, subprocess.SubprocessError):
        return None
    return out.stdout.strip()


def _version(package: str) -> str | None:
    try:
        return importlib.metadata.version(package)
    except importlib.metadata.PackageNotFoundError:
        return None


def environment(*, extra_packages: Sequence[str] = (), watched: Sequence[str] = ("jaxhand", "benchmarks")) -> dict:
    """What produced a benchmark's numbers: hardware, versions, commit (and whether the files
    under ``watched`` had uncommitted changes), load average."""
    dirty = _git("status", "--porcelain", "--untracked-files=no", "--", *watched)
    dev = jax.devices()[0]
    env = {
        "cpu": _cpu_name(),
        "cpu_count": os.cpu_count(),
        "device": f"{dev.platform}:{dev.device_kind}",
        "platform": f"{platform.system()} {platform.machine()}",
        "python": platform.python_version(),
        "jax": jax.__version__,
        "jaxlib": _version("jaxlib"),
        "numpy": np.__version__,
        "x64": bool(jax.config.jax_enable_x64),
        "xla_flags": os.environ.get("XLA_FLAGS", ""),
        "async_dispatch": bool(jax.config.read("jax_cpu_enable_async_dispatch")),
        "commit": _git("rev-parse", "--short=12", "HEAD"),
        "dirty": None if dirty is None else bool(dirty),
        "load_average_1min_start": load_average(),
        "date_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
    }
    for p in extra_packages:
        env[p] = _version(p)
    return env


def format_table(rows: Sequence[Sequence[object]], headers: Sequence[str]) -> str:
    """A plain-text table; floats get 3 significant digits (or 1 decimal above 100)."""
    def fmt(v):
        if isinstance(v, float):
            if not np.isfinite(v):
                return str(v)
            return f"{v:.1f}" if abs(v) >= 100 else f"{v:.3g}"
        return str(v)

    cells = [[fmt(v) for v in r] for r in rows]
    widths = [max(len(h), *(len(c[i]) for c in cells)) if cells else len(h) for i, h in enumerate(headers)]
    line = "  ".join(h.rjust(w) for h, w in zip(headers, widths))
    out = [line, "-" * len(line)]
    out += ["  ".join(c.rjust(w) for c, w in zip(r, widths)) for r in cells]
    return "\n".join(out)


def write_json(data: dict, path: str | Path) -> Path:
    """Write ``data`` as indented JSON (NumPy scalars and arrays converted), creating folders."""
    def conv(o):
        if isinstance(o, np.generic):
            return o.item()
        if isinstance(o, np.ndarray):
            return o.tolist()
        raise TypeError(f"not JSON serialisable: {type(o).__name__}")

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(data, indent=2, default=conv) + "\n")
    return path
