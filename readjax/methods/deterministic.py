"""The Deterministic baseline (METHOD.md section 10, supplement section 7): one ResNet18-based
regression from the RGB-D image to the motion, trained with the sum of per-key MSEs, in one
resumable stage ``deterministic/``. No retrieval, no sampling: ``generate`` returns the prediction
whatever M_R, the key and N are."""

from __future__ import annotations

from pathlib import Path

import jax
import jax.numpy as jnp

from readjax.methods import base, common
from readjax.methods.augment import augment_rgb
from readjax.models.resnet import DeterministicPlanner

METHOD = "deterministic"
SECTIONS = ("resnet",)
STAGES = ("deterministic",)


def build_model(configs: dict) -> DeterministicPlanner:
    return DeterministicPlanner(configs["resnet"])


def init_model(model: DeterministicPlanner, key):
    s = model.cfg.input_size
    return model.init(key, jnp.zeros((1, s, s, 4)))


def loss(model: DeterministicPlanner, augment: bool):
    def loss_fn(params, batch, rng):
        image = augment_rgb(rng, batch["image"]) if augment else batch["image"]
        return common.per_key_mse(model.apply(params, image), batch["motion"])

    return loss_fn


def train(task: str, data_root: str | Path, run_dir: str | Path, configs: dict, preset: str,
          stages=STAGES, progress: bool = True, stop_at: int | None = None) -> dict:
    """Train the Deterministic baseline for a task (resumes from the latest checkpoint)."""
    run = common.prepare(METHOD, task, data_root, run_dir, configs, preset, SECTIONS, configs["resnet"].input_size)
    model = build_model(run.configs)
    if "deterministic" in stages:
        spec, ds = base.network_stage_spec(run.train_cfg), run.ds

        def batch(idx, step, rows):
            idx = idx[rows]
            return {"image": ds.rgbd[idx], "motion": ds.motion[idx]}

        run.fit("deterministic", spec, init_model(model, jax.random.key(run.train_cfg.seed)),
                loss(model, run.train_cfg.augment), run.batches(spec, batch), progress, stop_at)
    return run.result()


class DeterministicModel(common.RunModel):
    """A trained Deterministic run. ``encode`` already predicts the motion; ``generate`` returns it."""

    uses_retrieval = False
    iterative = False

    def __init__(self, run_dir):
        super().__init__(run_dir)
        self.model = model = build_model(self.configs)
        self.params = self.network_params("deterministic",
                                          init_model(model, jax.random.key(self.configs["train"].seed)))
        self._predict = jax.jit(lambda p, x: model.apply(p, x))

    def encode(self, images: jax.Array) -> jax.Array:
        """The predicted motions (B, 101, 10): this model's per-image 'features'."""
        return self._predict(self.params, images)

    def generate(self, features, retrieved, key, n_steps: int) -> jax.Array:
        """The prediction ``encode`` made; ``retrieved``, ``key`` and ``n_steps`` are ignored."""
        return features
