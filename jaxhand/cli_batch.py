"""``jaxhand batch MANIFEST --out DIR``: run many ``track`` / ``fit-landmarks`` jobs on Dask."""

from __future__ import annotations

__all__ = ["register"]


def register(sub) -> None:
    p = sub.add_parser("batch", help="run the track / fit-landmarks jobs of a manifest in parallel (Dask)",
                       description="Run every job of MANIFEST (CSV or TOML; one job per row: name, command, its "
                                   "inputs and options, shared defaults at the top) into DIR/<job name>/, on a "
                                   "local Dask cluster of --workers processes or on the cluster behind "
                                   "--scheduler. Finished jobs (a complete summary.json) are skipped on a rerun; "
                                   "DIR/batch_summary.csv/.json/.png report every job.")
    p.add_argument("manifest", metavar="MANIFEST", help="the jobs: a .csv or .toml file")
    p.add_argument("--out", required=True, metavar="DIR", help="batch folder: one folder per job and the report")
    p.add_argument("--workers", type=int, default=None, metavar="N",
                   help="local worker processes, one thread each (default: the CPU cores, at most one per job)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="a running Dask scheduler (tcp://host:8786) to use instead of a local cluster")
    p.set_defaults(func=_batch)


def _batch(args) -> int:
    from .batch import load_manifest, run_batch

    manifest = load_manifest(args.manifest)     # the whole manifest is checked before any job starts
    try:
        rows = run_batch(manifest, args.out, workers=args.workers, scheduler=args.scheduler)
    except KeyboardInterrupt:
        return 130
    return 1 if any(r["status"] == "failed" for r in rows) else 0
