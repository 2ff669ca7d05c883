"""``jaxhand batch``: many ``track`` / ``fit-landmarks`` jobs from one manifest, on Dask.

- :func:`load_manifest`: read and validate a CSV or TOML manifest into :class:`Job` s;
- :func:`run_batch`: run the unfinished jobs on a local Dask cluster (or a running scheduler),
  each in-process in a long-lived worker, and write the batch report;
- :func:`run_job`: one job in this process (what a worker runs);
- :func:`write_batch_summary`: ``batch_summary.csv`` / ``.json`` / ``.png`` from the jobs' records.
"""

from ._manifest import COMMANDS as COMMANDS
from ._manifest import MANIFEST_VERSION as MANIFEST_VERSION
from ._manifest import Job as Job
from ._manifest import Manifest as Manifest
from ._manifest import load_manifest as load_manifest
from ._manifest import parse_manifest as parse_manifest
from ._runner import WORKER_ENV as WORKER_ENV
from ._runner import finished_summary as finished_summary
from ._runner import pinned_environment as pinned_environment
from ._runner import run_batch as run_batch
from ._runner import run_job as run_job
from ._summary import COLUMNS as COLUMNS
from ._summary import summary_rows as summary_rows
from ._summary import write_batch_summary as write_batch_summary

__all__ = ["COMMANDS", "MANIFEST_VERSION", "Job", "Manifest", "load_manifest", "parse_manifest", "WORKER_ENV",
           "finished_summary", "pinned_environment", "run_batch", "run_job", "COLUMNS", "summary_rows",
           "write_batch_summary"]
