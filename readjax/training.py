"""Training loop machinery shared by every model: train state, a jitted (donated, sharded) train
step, orbax checkpoints that resume exactly, a JSONL metrics log and a loss-curve PNG.

A model supplies ``loss_fn(params, batch, rng) -> (loss, metrics)`` and initial parameters; the data
side supplies ``sample_batch(step) -> batch`` — a pure function of the step, so a run killed and
resumed from its latest checkpoint sees exactly the batches an uninterrupted run would have seen
(no step lost, none repeated). The batch is sharded over ``jax.devices()`` on its leading axis;
in a multi-process training (:mod:`readjax.distributed`) those are every process's devices, each
process builds its rows of the batch, every process checkpoints (orbax writes once) and only the
primary writes the stage's records.
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

import jax
import jax.numpy as jnp
import numpy as np
import optax
import orbax.checkpoint as ocp
from flax import struct
from tqdm.auto import tqdm

from readjax import atomic_write, distributed, provenance, sharding, stage_folder
from readjax.stage_identity import (CheckpointError, check_shareable_stage, copy_finished_stage,  # noqa: F401
                                    identity_mismatch, with_new_defaults)  # noqa: F401  (re-exported)


@struct.dataclass
class TrainState:
    step: jax.Array
    params: Any
    opt_state: Any


@dataclass(frozen=True)
class StageSpec:
    """What one training stage (e.g. "vae", "read") needs besides the model."""

    steps: int
    batch_size: int
    lr: float = 1e-4
    lr_decay: float = 1.0  # multiplied every lr_decay_every steps (staircase); 1 = constant
    lr_decay_every: int = 5000
    schedule: str = "staircase"  # or "cosine": lr -> 0 along one cosine over ``steps`` (lr_decay unused)
    grad_clip: float = 1.0
    ckpt_every: int = 500
    log_every: int = 25
    keep: int = 3
    seed: int = 0
    val_every: int = 250  # validation loss every this many steps (when the stage has validation batches)
    stop_patience: int = 0  # stop when the validation loss has not improved for this many steps (0 = never)
    stop_min_delta: float = 0.01  # an improvement must beat the best so far by this fraction


def stop_decision(history: list[tuple[int, float]], spec: StageSpec) -> dict | None:
    """The convergence rule on a validation history [(step, loss), ...] (in step order): stop once
    no loss has beaten the best before it by more than ``stop_min_delta`` (relative) within the last
    ``stop_patience`` steps. Returns the record of why (``stop.json``) or None to go on."""
    if spec.stop_patience <= 0 or not history:
        return None
    best_step, best = history[0]
    for step, loss in history[1:]:
        if loss < best * (1.0 - spec.stop_min_delta):
            best_step, best = step, loss
    last = history[-1][0]
    if last - best_step < spec.stop_patience:
        return None
    return {"stopped_at": last, "reason": "converged", "best_val_loss": best, "best_step": best_step,
            "rule": f"validation loss not improved by more than {spec.stop_min_delta:.0%} over the last "
                    f"{spec.stop_patience} steps (best {best:.4g} at step {best_step})"}


def learning_rate(spec: StageSpec):
    """The stage's learning rate: a schedule of the step (``TrainConfig.schedule``) or a constant."""
    if spec.schedule == "cosine":
        return optax.cosine_decay_schedule(spec.lr, spec.steps)
    if spec.schedule != "staircase":
        raise ValueError(f"unknown schedule {spec.schedule!r}; use 'staircase' or 'cosine'")
    if spec.lr_decay != 1.0:
        return optax.exponential_decay(spec.lr, spec.lr_decay_every, spec.lr_decay, staircase=True)
    return spec.lr


def make_optimizer(spec: StageSpec) -> optax.GradientTransformation:
    lr = learning_rate(spec)
    return optax.chain(optax.clip_by_global_norm(spec.grad_clip), optax.adam(lr))


def make_train_step(loss_fn: Callable, optimizer: optax.GradientTransformation, base_key: jax.Array):
    """jit(train_step) with the state donated, batch sharded on axis 0, state replicated."""

    def train_step(state: TrainState, batch):
        rng = jax.random.fold_in(base_key, state.step)
        (loss, metrics), grads = jax.value_and_grad(loss_fn, has_aux=True)(state.params, batch, rng)
        updates, opt_state = optimizer.update(grads, state.opt_state, state.params)
        params = optax.apply_updates(state.params, updates)
        metrics = dict(metrics, loss=loss, grad_norm=optax.tree.norm(grads))
        return TrainState(step=state.step + 1, params=params, opt_state=opt_state), metrics

    return jax.jit(train_step, donate_argnums=(0,))


class Stage:
    """One training stage in ``run_dir/<name>/`` (its files: :mod:`readjax.stage_folder`)."""

    def __init__(self, run_dir: str | Path, name: str, spec: StageSpec, config: dict, fingerprint: str):
        self.dir = Path(run_dir) / name
        # compare configs as JSON sees them (tuples become lists on disk)
        self.name, self.spec, self.fingerprint = name, spec, fingerprint
        self.config = json.loads(json.dumps(config))
        self.dir.mkdir(parents=True, exist_ok=True)
        self._check_identity()
        options = ocp.CheckpointManagerOptions(max_to_keep=spec.keep, create=True,
                                               enable_async_checkpointing=False)
        # orbax refuses relative paths (`--out runs` is the CLI default): hand it an absolute one
        self.manager = ocp.CheckpointManager((self.dir / "checkpoints").absolute(), options=options,
                                             item_names=("state",))

    # -------------------------------------------------------------- identity
    def _check_identity(self) -> None:
        """Refuse to resume a stage trained on another dataset or config (nothing is touched)."""
        f = self.dir / stage_folder.STAGE_FILE
        meta = {"stage": self.name, "config": self.config, "dataset_fingerprint": self.fingerprint}
        if f.exists():
            why = identity_mismatch(f, self.config, self.fingerprint)
            if why:
                raise CheckpointError(f"{self.dir} {why}; use a new --out (or --restart to overwrite)")
        elif distributed.is_primary():
            atomic_write.write_text(f, json.dumps(dict(meta, versions=provenance.versions()), indent=2, sort_keys=True))

    # -------------------------------------------------------------- checkpoints
    def latest_step(self) -> int | None:
        return self.manager.latest_step()

    def save(self, state: TrainState, force: bool = False) -> None:
        step = int(state.step)
        self.manager.save(step, args=ocp.args.Composite(state=ocp.args.StandardSave(state)), force=force)
        self.manager.wait_until_finished()

    def restore(self, template: TrainState, step: int | None = None) -> TrainState:
        step = self.latest_step() if step is None else step
        if step is None:
            raise CheckpointError(f"no checkpoint in {self.dir / 'checkpoints'}")
        abstract = jax.tree.map(ocp.utils.to_shape_dtype_struct, template)
        try:
            out = self.manager.restore(step, args=ocp.args.Composite(state=ocp.args.StandardRestore(abstract)))
        except Exception as e:  # orbax raises many types for damaged files
            raise CheckpointError(
                f"checkpoint {self.dir / 'checkpoints' / str(step)} cannot be restored ({type(e).__name__}: "
                f"{e}); delete that step folder to fall back to an earlier one") from e
        return out["state"]

    # -------------------------------------------------------------- training
    def stop_record(self) -> dict | None:
        """Why and when this stage finished (``stop.json``), or None while it has not."""
        return stage_folder.read_stop(self.dir)

    def fit(self, params, loss_fn: Callable, sample_batch: Callable[[int], Any], progress: bool = True,
            stop_at: int | None = None, val_batches: list | None = None) -> TrainState:
        """Train to ``spec.steps`` (resuming from the latest checkpoint); returns the final state.

        ``val_batches``: fixed held-out batches; every ``spec.val_every`` steps their mean loss
        (fixed noise) is logged as ``val_loss`` and, with ``spec.stop_patience``, the convergence
        rule (:func:`stop_decision`) may end the stage early. A finished stage records when and why
        in ``stop.json`` and returns at once when fitted again. ``stop_at`` ends early at that step
        (after checkpointing), to test resuming.
        """
        spec = self.spec
        optimizer = make_optimizer(spec)
        state = TrainState(step=jnp.zeros((), jnp.int32), params=params, opt_state=optimizer.init(params))
        state = sharding.replicate(state)
        if self.latest_step() is not None:
            state = self.restore(state)
        start = int(state.step)
        finished = self.stop_record()
        if finished is not None and finished["stopped_at"] == start:
            return state  # finished before (converged or at the cap)
        # lines past the checkpoint are ignored (every process) and dropped (the primary): recomputed below
        history = [(r["step"], r["val_loss"]) for r in self.metrics() if "val_loss" in r and r["step"] <= start]
        primary = distributed.is_primary()
        if primary:
            self._truncate_metrics(start)
        step_fn = make_train_step(loss_fn, optimizer, jax.random.key(spec.seed))
        val_loss = make_val_loss(loss_fn, val_batches, spec.seed) if val_batches else None
        end = spec.steps if stop_at is None else min(stop_at, spec.steps)
        bar = _bar(progress and primary, self.name, spec.steps, start)
        log = open(self.dir / stage_folder.METRICS_FILE, "a") if primary else None
        t0, acc, stop = time.time(), [], None
        try:
            for step in range(start, end):
                batch = distributed.global_batch(sample_batch, step, spec.batch_size)
                state, metrics = step_fn(state, batch)
                acc.append(metrics)
                validate = val_loss is not None and ((step + 1) % spec.val_every == 0 or step + 1 == spec.steps)
                if (step + 1) % spec.log_every == 0 or step + 1 == end or validate:
                    m = {k: float(np.mean([float(a[k]) for a in acc])) for k in acc[0]}
                    acc = []
                    if validate:
                        m["val_loss"] = val_loss(state.params)
                        history.append((step + 1, m["val_loss"]))
                        stop = stop_decision(history, spec)
                    if not all(math.isfinite(v) for v in m.values()):
                        raise FloatingPointError(f"{self.name}: non-finite metrics at step {step + 1}: {m}")
                    if log is not None:
                        log.write(json.dumps({"step": step + 1, "time_s": round(time.time() - t0, 2), **m}) + "\n")
                        log.flush()
                    bar.set_postfix(loss=f"{m['loss']:.4g}", **({"val": f"{m['val_loss']:.4g}"} if validate else {}))
                if (step + 1) % spec.ckpt_every == 0 or step + 1 == end or stop is not None:
                    self.save(state)
                bar.update(1)
                if stop is not None:
                    break
        finally:
            bar.close()
            if log is not None:
                log.close()
        if stop is None and int(state.step) == spec.steps:
            stop = {"stopped_at": spec.steps, "reason": "step cap", "rule": f"{spec.steps} steps"}
            if history:
                best_step, best = min(history, key=lambda h: h[1])
                stop.update(best_val_loss=best, best_step=best_step)
        if primary:
            if stop is not None:
                atomic_write.write_text(self.dir / stage_folder.STOP_FILE, json.dumps(stop, indent=2))
            self.plot()
        distributed.barrier(f"{self.dir}:fitted")  # the others read stop.json only once it is there
        return state

    def _truncate_metrics(self, step: int) -> None:
        """Drop log lines past the checkpoint we resume from (they will be recomputed)."""
        f = self.dir / stage_folder.METRICS_FILE
        if not f.exists():
            return
        keep = [ln for ln in f.read_text().splitlines() if ln.strip() and json.loads(ln)["step"] <= step]
        atomic_write.write_text(f, "".join(ln + "\n" for ln in keep))

    def metrics(self) -> list[dict]:
        return stage_folder.read_metrics(self.dir)

    def plot(self) -> Path | None:
        return stage_folder.plot_losses(self.dir, f"{self.name} training losses")


def make_val_loss(loss_fn: Callable, batches: list, seed: int) -> Callable[[Any], float]:
    """params -> mean loss over the fixed validation ``batches``, each with its own fixed key (the
    same noise at every validation, so the curve moves with the parameters only)."""
    loss = jax.jit(lambda p, b, k: loss_fn(p, b, k)[0])
    keys = [jax.random.fold_in(jax.random.key(seed), 10_000_000 + i) for i in range(len(batches))]
    batches = [sharding.shard_batch(b) for b in batches]

    def val_loss(params) -> float:
        return float(np.mean([float(loss(params, b, k)) for b, k in zip(batches, keys)]))

    return val_loss


def _bar(enabled: bool, name: str, total: int, initial: int):
    return tqdm(total=total, initial=initial, desc=name, unit="step", disable=not enabled, dynamic_ncols=True)


def batch_indices(n: int, batch: int, seed: int, step: int) -> np.ndarray:
    """The batch drawn at ``step``: a pure function of (seed, step), so resuming is exact."""
    return np.random.default_rng([seed, step]).integers(0, n, size=batch)
