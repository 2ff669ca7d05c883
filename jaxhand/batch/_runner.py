"""Running a manifest's jobs on Dask workers, in-process, with resumption and a combined report.

Each job is one call of the command line's own entry point, ``jaxhand.cli.main(argv)``, inside a
long-lived worker process: the worker imports jax once and keeps its compiled programs (the
tracker's frame step is cached per model structure and settings), so only a worker's first job of
each structure compiles. Every job writes exactly what the single command writes, frame by frame,
into ``DIR/<job name>/``, plus ``batch.log`` (its printed output) and, when it fails,
``error.json``.

A job whose folder holds a complete ``summary.json`` (the single command writes it last) is
finished: a rerun skips it. A failed job records its error and the others go on; a rerun tries
it again.
"""

from __future__ import annotations

import contextlib
import json
import os
import socket
import sys
import time
import traceback
from pathlib import Path

from .._compiled_cache import release_compiled
from .._errors import InputError
from ._manifest import Job, Manifest
from ._summary import write_batch_summary

__all__ = ["run_batch", "run_job", "finished_summary", "pinned_environment", "WORKER_ENV"]

#: What pins a worker's JAX/XLA and BLAS to one thread: set before the worker process starts (its
#: imports of numpy and jax read them), so N workers use N cores.
WORKER_ENV = {
    "OMP_NUM_THREADS": "1",
    "OPENBLAS_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
    "XLA_FLAGS": "--xla_cpu_multi_thread_eigen=false",
}
ERROR_FILE, LOG_FILE = "error.json", "batch.log"
#: jax.monitoring's event for one XLA compilation (counted per job in the report).
_COMPILE_EVENT = "/jax/core/compile/backend_compile_duration"
_compiles = {"count": 0, "seconds": 0.0, "listening": False}


def finished_summary(job_dir: str | Path) -> dict | None:
    """The job's ``summary.json`` if it is complete (valid JSON with its frame count), else None."""
    try:
        summary = json.loads((Path(job_dir) / "summary.json").read_text())
    except (OSError, ValueError):
        return None
    return summary if isinstance(summary, dict) and "frames" in summary else None


def _count_compiles(event: str, duration_s: float, **_) -> None:
    if event == _COMPILE_EVENT:
        _compiles["count"] += 1
        _compiles["seconds"] += duration_s


def _error_line(log: str) -> str | None:
    """The last ``jaxhand CMD: error: ...`` or argparse ``error:`` line of a job's output."""
    lines = [ln for ln in log.splitlines() if "error:" in ln]
    return lines[-1].strip() if lines else None


def run_job(name: str, argv: list[str], job_dir: str | Path) -> dict:
    """Run one job in this process: ``jaxhand.cli.main(argv)`` with its output in ``batch.log``.

    This is what a Dask worker runs. Never raises for a failing job: its error goes into
    ``error.json`` in its folder and into the returned record.

    Returns:
        ``name``, ``status`` (``done`` | ``failed``), ``exit_code``, ``error`` (one line or None),
        ``wall_s``, ``jit_compiles`` and ``compile_s`` (XLA compilations this job caused; 0 when
        the worker had compiled its structure already), ``worker`` (host:pid) and ``summary``
        (its ``summary.json``, or None).
    """
    import jax

    from ..cli import main

    job_dir = Path(job_dir)
    job_dir.mkdir(parents=True, exist_ok=True)
    # Leftovers of an earlier failed or interrupted try: this try's files replace them.
    for stale in (ERROR_FILE, "summary.json"):
        (job_dir / stale).unlink(missing_ok=True)
    if not _compiles["listening"]:
        jax.monitoring.register_event_duration_secs_listener(_count_compiles)
        _compiles["listening"] = True
    n0, s0 = _compiles["count"], _compiles["seconds"]
    tb = None
    t0 = time.perf_counter()
    with open(job_dir / LOG_FILE, "w") as log, contextlib.redirect_stdout(log), contextlib.redirect_stderr(log):
        print(f"$ jaxhand {' '.join(argv)}", flush=True)
        try:
            code = main(list(argv))
        except SystemExit as err:               # argparse: usage error (printed above)
            code = err.code if isinstance(err.code, int) else 2
        except Exception:                       # a bug or an unexpected failure: keep the traceback
            tb = traceback.format_exc()
            print(tb, flush=True)
            code = None
    wall_s = time.perf_counter() - t0
    release_compiled(0.5)   # a worker that ran jobs of many shapes holds their programs' memory maps
    summary = finished_summary(job_dir) if code == 0 else None
    record = {"name": name, "status": "done" if summary is not None else "failed", "exit_code": code,
              "error": None, "wall_s": wall_s, "jit_compiles": _compiles["count"] - n0,
              "compile_s": _compiles["seconds"] - s0, "worker": f"{socket.gethostname()}:{os.getpid()}",
              "summary": summary}
    if summary is None:
        if tb is not None:
            record["error"] = tb.strip().splitlines()[-1]
        else:
            line = _error_line((job_dir / LOG_FILE).read_text())
            record["error"] = line or (f"exit status {code}" if code else "no complete summary.json written")
        (job_dir / ERROR_FILE).write_text(json.dumps({**{k: v for k, v in record.items() if k != "summary"},
                                                      "argv": list(argv), "traceback": tb}, indent=2) + "\n")
    return record


@contextlib.contextmanager
def pinned_environment(env: dict[str, str] = WORKER_ENV):
    """Dask's ``distributed.nanny.pre-spawn-environ`` extended with ``env`` while a LocalCluster
    starts, so each worker process is created with it (numpy and jax read these variables on
    import, before any task could set them). The nanny sets them in this process too before every
    spawn, so this process's own environment is put back on exit."""
    import dask

    saved = dict(os.environ)
    merged = dict(env)
    if os.environ.get("XLA_FLAGS") and "XLA_FLAGS" in env:   # keep the user's flags, add the pins
        merged["XLA_FLAGS"] = f"{os.environ['XLA_FLAGS']} {env['XLA_FLAGS']}"
    os.environ.update(merged)     # the nanny takes a variable's value from os.environ over the config
    pre = {**dask.config.get("distributed.nanny.pre-spawn-environ", {}), **merged}
    try:
        with dask.config.set({"distributed.nanny.pre-spawn-environ": pre}):
            yield
    finally:
        os.environ.clear()
        os.environ.update(saved)


#: Seconds a local cluster may have no worker (all died and could not be restarted) before the
#: jobs still waiting are failed.
NO_WORKER_TIMEOUT_S = 120.0


def _workerless(client, since: float | None) -> float | None:
    """Since when (``time.monotonic``) the cluster has had no worker, or None while it has one."""
    if client.nthreads():
        return None
    return time.monotonic() if since is None else since


def _progress_bars(total: int, enabled: bool):
    from tqdm import tqdm

    jobs = tqdm(total=total, desc="jobs", unit="job", disable=not enabled, position=0)
    frames = tqdm(desc="frames", unit="frame", disable=not enabled, position=1)
    return jobs, frames


def _rows_written(job_dir: Path) -> int:
    """Frames a running job has written so far (rows of its ``angles.csv`` after the header)."""
    try:
        with open(job_dir / "angles.csv", "rb") as f:
            return max(0, sum(1 for _ in f) - 1)
    except OSError:
        return 0


def run_batch(manifest: Manifest, out_dir: str | Path, *, workers: int | None = None, scheduler: str | None = None,
              progress: bool | None = None, log=None) -> list[dict]:
    """Run every unfinished job of ``manifest`` on Dask and write the batch summary.

    Args:
        out_dir: the batch folder: one folder per job, ``batch_summary.csv``/``.json``/``.png``.
        workers: local worker processes (default: the CPU cores, at most the number of jobs to
            run); ignored with ``scheduler``.
        scheduler: address of a running Dask scheduler (``tcp://host:8786``) to use as it is,
            instead of a local cluster.
        progress: progress bars over jobs and frames (default: when stderr is a terminal).
        log: where messages go (default stderr).

    Returns:
        One record per job, in manifest order (see :func:`jaxhand.batch.summary_rows`).
    """
    log = sys.stderr if log is None else log
    out = Path(out_dir).absolute()      # the workers' working folder may differ from ours
    out.mkdir(parents=True, exist_ok=True)
    if workers is not None and workers < 1:
        raise InputError(f"--workers: expected an integer >= 1, got {workers}")
    records: dict[str, dict] = {}
    todo: list[Job] = []
    for job in manifest.jobs:
        summary = finished_summary(out / job.name)
        if summary is None:
            todo.append(job)
        else:
            records[job.name] = {"name": job.name, "status": "skipped", "summary": summary}
    if records:
        print(f"jaxhand batch: {len(records)} of {len(manifest.jobs)} jobs finished earlier, skipped", file=log)
    interrupted = False
    try:
        if todo:
            _run_jobs(todo, out, workers, scheduler, records,
                      sys.stderr.isatty() if progress is None else progress, log)
    except KeyboardInterrupt:
        interrupted = True
        for job in todo:   # cut short: its finished frames are in its angles.csv, the rerun starts it over
            if job.name not in records and (out / job.name / "angles.csv").exists():
                records[job.name] = {"name": job.name, "status": "interrupted", "summary": None}
    rows = write_batch_summary(manifest, out, records)
    done = sum(r["status"] in ("done", "skipped") for r in rows)
    failed = [r for r in rows if r["status"] == "failed"]
    if interrupted:
        cut = sum(r["status"] == "interrupted" for r in rows)
        print(f"jaxhand batch: interrupted; {done} of {len(rows)} jobs finished, {cut} cut short (their finished "
              "frames are in their angles.csv); run the same command again to resume", file=log)
        raise KeyboardInterrupt
    for r in failed:
        print(f"jaxhand batch: job {r['name']!r} failed: {r['error']} (see {out / r['name'] / ERROR_FILE})", file=log)
    print(f"jaxhand batch: {done} of {len(rows)} jobs finished, {len(failed)} failed -> "
          f"{out / 'batch_summary.csv'}", file=log)
    return rows


def _run_jobs(todo: list[Job], out: Path, workers, scheduler, records: dict, show: bool, log) -> None:
    from distributed import Client, LocalCluster, as_completed

    stack = contextlib.ExitStack()
    with stack:
        if scheduler:
            try:
                client = stack.enter_context(Client(scheduler, timeout="30s"))
            except OSError as err:
                raise InputError(f"--scheduler: cannot connect to {scheduler!r} ({err})") from err
        else:
            n = workers or min(os.cpu_count() or 1, len(todo))
            with pinned_environment():
                # No dashboard, and the scheduler's HTTP endpoints on a free port: several batches
                # (or other Dask clusters) on one machine then start without clashing over 8787.
                cluster = stack.enter_context(LocalCluster(
                    n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None,
                    scheduler_kwargs={"dashboard": False, "dashboard_address": "127.0.0.1:0"}))
            client = stack.enter_context(Client(cluster))   # closed before the cluster
        n_workers = len(client.nthreads()) if scheduler else n
        print(f"jaxhand batch: {len(todo)} job(s) on {n_workers} worker(s)"
              f"{f' at {scheduler}' if scheduler else ''}", file=log)
        futures = {client.submit(run_job, job.name, job.argv(out), str(out / job.name), pure=False,
                                 key=f"jaxhand-batch-{job.name}-{time.time_ns()}"): job for job in todo}
        jobs_bar, frames_bar = _progress_bars(len(todo), show)
        finished_frames = 0
        no_workers_since, checked = None, time.monotonic()
        try:
            pending = as_completed(futures)
            while not pending.is_empty():
                if not scheduler and time.monotonic() - checked > 5.0:
                    checked = time.monotonic()
                    no_workers_since = _workerless(client, no_workers_since)
                if no_workers_since is not None and time.monotonic() - no_workers_since > NO_WORKER_TIMEOUT_S:
                    for fut, job in futures.items():     # nothing left to run them: fail them, keep the rest
                        if job.name not in records:
                            fut.cancel()
                            records[job.name] = {"name": job.name, "status": "failed", "summary": None,
                                                 "error": "the local cluster lost all its workers"}
                    break
                for fut in pending.next_batch(block=False):
                    job = futures[fut]
                    try:
                        record = fut.result()
                    except Exception as err:    # the worker died (e.g. out of memory): the job failed
                        record = {"name": job.name, "status": "failed", "error": f"{type(err).__name__}: {err}",
                                  "summary": None}
                    records[job.name] = record
                    finished_frames += (record.get("summary") or {}).get("frames", 0)
                    jobs_bar.update(1)
                if show:
                    running = [futures[f] for f in futures if f.status == "pending"]
                    frames_bar.n = finished_frames + sum(_rows_written(out / j.name) for j in running)
                    frames_bar.refresh()
                time.sleep(0.25)
        except KeyboardInterrupt:
            for fut in futures:
                fut.cancel()
            raise
        finally:
            jobs_bar.close()
            frames_bar.close()
