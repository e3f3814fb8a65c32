"""Batch detection over many recordings: process pool, Dask LocalCluster or a remote cluster.

``run_batch(inputs, outdir)`` plans one *job* per input (one per LaserScan topic for a bag
with several), runs the jobs in parallel and writes, in ``outdir``:

* ``<name>.parquet`` per job: one row per keypoint, the columns of
  :data:`laser_corners.io.writers.TABLE_COLUMNS` (``map_x, map_y`` too when the recording
  has poses), written by :class:`~laser_corners.io.writers.ParquetKeypointWriter` with the
  resolved parameters and the input path in the schema metadata;
* ``manifest.jsonl``: one JSON record per finished job, appended (and flushed to disk) as
  each job ends: ``input, topic, output, status ("done" or "failed"), scans, keypoints,
  skipped, seconds, read_seconds, detect_seconds, write_seconds, startup_seconds, error,
  worker``;
* ``batch-params.yaml``: the parameter choice every job of the folder used.

Inputs that exist but are not recordings (a ``.relations`` file, a README) are skipped, each
with a one-line reason in :attr:`BatchReport.skipped`; they are not failures.

Resuming: a job whose input (and topic) has a ``done`` record in the manifest and whose
Parquet file exists is skipped. A job writes ``<name>.parquet.partial``; the batch renames it
to ``<name>.parquet`` only after the writer closed, as it records the job in the manifest, so
a partial file is never taken for a result and a named one always has its record; a leftover
``.partial`` is overwritten when its job runs again. A job that fails (a known error: one
line; anything else: the exception's first line, with the traceback in ``errors/<name>.txt``)
is recorded as ``failed`` and the other jobs go on; the next run retries it.

Where the time goes is recorded per job: ``read_seconds`` (the reader: file decoding and
:class:`~laser_corners.LaserScan` construction), ``detect_seconds`` (the numba kernel),
``write_seconds`` (the Parquet writer) and ``startup_seconds`` (loading numba's cached
kernels, once per worker process); a reader thread reads ahead while the kernels run
(``reader_seconds``; ``read_seconds`` is then the wait it could not hide). Workers of the
process pool die with the batch process, even when it is killed. See
``docs/batch-and-viewer.md``.

Modules: :mod:`~laser_corners.batch.plan` (jobs, names, skipped inputs),
:mod:`~laser_corners.batch.manifest` (jobs, results, the manifest),
:mod:`~laser_corners.batch.worker` (one job), :mod:`~laser_corners.batch.executors` (process
pool, Dask), :mod:`~laser_corners.batch.run` (:func:`run_batch`).
"""

from laser_corners.batch import manifest
from laser_corners.batch.manifest import (
    MANIFEST_NAME,
    PARAMS_NAME,
    PARTIAL_SUFFIX,
    BatchJob,
    BatchReport,
    JobResult,
    Manifest,
    SkippedInput,
)
from laser_corners.batch.plan import plan_inputs, plan_jobs
from laser_corners.batch.run import run_batch
from laser_corners.batch.worker import run_job
from laser_corners.pipeline import CHUNK_SCANS, ParamsChoice

__all__ = [
    *manifest.__all__,
    "CHUNK_SCANS",
    "ParamsChoice",
    "plan_inputs",
    "plan_jobs",
    "run_batch",
    "run_job",
]
