"""One training across processes and machines with JAX's multi-controller engine, ``jax.distributed``.

Every process runs the same command (``python -m experiments.train ... --distributed``) on its own
devices. Once :func:`initialize` has run, ``jax.devices()`` lists every process's devices, so the
one-axis mesh of :mod:`readjax.sharding` spans them all: a train step is one SPMD program over the
global batch, its gradient all-reduce crossing processes (gloo on the CPU, NCCL on GPUs).

- Who is who: :func:`initialize` takes the coordinator address (``HOST:PORT``, process 0's machine),
  the process count and this process's index from its arguments, else from ``JAX_COORDINATOR_ADDRESS``,
  ``JAX_NUM_PROCESSES`` and ``JAX_PROCESS_ID``, else from JAX's cluster auto-detection (SLURM's
  ``SLURM_*`` variables under ``srun``, Open MPI, Kubernetes...).
- Data: each process builds only the rows of each global batch its devices hold
  (:func:`readjax.sharding.process_rows`), from the same demo indices and per-step choices a
  one-process run draws, and the global array is assembled with
  ``jax.make_array_from_process_local_data``. The step's noise (augmentation, diffusion time and
  noise) is drawn inside the jitted step for the global shapes, so the training is the one-process
  training with the same global batch, to float rounding.
- Files: every process reads the run folder (identity checks, resume); only the primary (process 0)
  writes the records (``run.json``, ``stage.json``, statistics, ``metrics.jsonl``, ``stop.json``,
  ``loss.png``). Checkpoints are saved by every process through orbax, which writes each array once
  and commits the step on the primary; every process restores from them. The run folder must be on
  a file system every process sees (one machine, NFS, a mounted bucket).

One process (no ``--distributed``) is the special case: nothing here changes its behaviour.
"""

from __future__ import annotations

import os

import jax

ENV_COORDINATOR, ENV_NUM_PROCESSES, ENV_PROCESS_ID = "JAX_COORDINATOR_ADDRESS", "JAX_NUM_PROCESSES", "JAX_PROCESS_ID"


def _env_int(name: str) -> int | None:
    value = os.environ.get(name)
    if value in (None, ""):
        return None
    try:
        return int(value)
    except ValueError:
        raise ValueError(f"{name}={value!r} is not an integer") from None


def initialize(coordinator: str | None = None, num_processes: int | None = None,
               process_id: int | None = None) -> tuple[int, int]:
    """Join the multi-process training (before any JAX computation in this process); returns
    (this process's index, process count). Unset values come from the environment (module doc);
    what is still unset JAX detects from the cluster (SLURM...) or refuses."""
    coordinator = coordinator or os.environ.get(ENV_COORDINATOR) or None
    num_processes = num_processes if num_processes is not None else _env_int(ENV_NUM_PROCESSES)
    process_id = process_id if process_id is not None else _env_int(ENV_PROCESS_ID)
    if num_processes is not None and process_id is not None and not 0 <= process_id < num_processes:
        raise ValueError(f"process id {process_id} is not one of the {num_processes} processes (0..{num_processes - 1})")
    # CPU collectives between processes (the GPU backends bring their own): set before the backend starts
    jax.config.update("jax_cpu_collectives_implementation", "gloo")
    jax.distributed.initialize(coordinator_address=coordinator, num_processes=num_processes, process_id=process_id)
    return jax.process_index(), jax.process_count()


def is_primary() -> bool:
    """Whether this process writes the run's records (process 0; always, in a one-process run)."""
    return jax.process_index() == 0


def barrier(name: str) -> None:
    """Wait until every process reaches the barrier ``name`` (nothing in a one-process run). Every
    process must pass the same barriers in the same order."""
    if jax.process_count() > 1:
        from jax.experimental import multihost_utils

        multihost_utils.sync_global_devices(name)


def global_batch(sample_batch, step: int, batch_size: int):
    """The training batch of ``step`` on the mesh. ``sample_batch(step)`` builds the whole batch; one
    that offers ``sample_batch.rows(step, rows)`` (:class:`readjax.methods.base.Batches`) builds only
    this process's rows in a multi-process run (others build all and keep theirs)."""
    from readjax import sharding

    part = getattr(sample_batch, "rows", None)
    if jax.process_count() == 1 or part is None:
        return sharding.shard_batch(sample_batch(step))
    return sharding.shard_rows(part(step, sharding.process_rows(batch_size)), batch_size)
