"""The training step, timed and profiled (``python -m experiments.bench train``).

READ trains in two stages (METHOD.md sections 4-6): the motion autoencoder, then the denoiser.
This benchmark runs both stages' real jitted train steps (``readjax.training.make_train_step``:
donated state, sharded batch, Adam) on synthetic data of a preset's sizes — step time does not
depend on the values — and reports, in one ``parts`` row per preset:

* ``read_step_ms`` / ``vae_step_ms``: ms per train step of each stage, as the preset trains it (the cpu
  preset's READ step is self-fed: ``sde.self_feed = 0.5``, one more gradient-free denoiser pass), with
  ``read_plain_step_ms``, READ's step on the paper's loss (``sde.self_feed = 0``), and ``host_batch_ms``, the
  batch (sampling + device copy) that the loop builds while the previous step runs;
* each piece of the denoiser's step timed alone (autoencoder decode, augmentation, UNet trunk
  forward / forward + backward, denoiser given the image features, the Adam update);
* ``flops``: XLA's cost analysis of each step (GFLOP and GB accessed per step);
* ``profile`` (``--profile``): a trace of each step (``jax.profiler``), each executed XLA op
  attributed through the compiled program's metadata to the model part that emitted it (the
  denoiser's parts; the autoencoder's kinds of layer), forward and backward apart — where the
  time goes.

Only ratios within one run mean anything on a shared machine. ``--compare JSON`` flags every timing
that got >= ``--slower`` x slower than a previous run of this benchmark (a regression check).
"""

from __future__ import annotations

import collections
import dataclasses
import glob
import gzip
import json
import os
import re
import statistics
import tempfile
import time

from readjax.lab.bench_common import synthetic_dataset

# Where an XLA op's time goes, by the module path in its metadata (first match wins: feature
# sampling runs inside ``unet.head_at``, so it is matched before the UNet).
PROFILE_PARTS = (
    ("feature sampling", ("track_tokens", "image_tokens", "input_at", "head_at")),
    ("UNet image encoder", ("unet",)),
    ("transformer layers", ("layers_",)),
    ("token embeddings", ("motion_embed", "time_embed", "input_embed", "image_proj")),
    ("output heads", ("heads_",)),
    ("autoencoder", ("MotionVAE", "KinematicAE", "body/", "encoder/")),
    ("augmentation", ("augment",)),
)
# The autoencoder's step, by kind of layer.
VAE_PROFILE_PARTS = (
    ("self-attention", ("self_attn",)),
    ("cross-attention", ("cross_attn",)),
    ("feed-forward", ("ffn",)),
    ("layer norms", ("norm",)),
    ("frame embedding", ("frame_embed",)),
    ("output heads", ("heads_",)),
)


def _median_ms(fn, repeats: int) -> float:
    """Median ms of ``fn`` (blocked until ready) after two warm-up calls (compile, caches)."""
    import jax

    jax.block_until_ready(fn())
    jax.block_until_ready(fn())
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        jax.block_until_ready(fn())
        times.append(time.perf_counter() - t)
    return round(1e3 * statistics.median(times), 2)


class _Stepper:
    """A jitted train step and its (donated) state, stepped on a fixed batch."""

    def __init__(self, loss_fn, params, spec, batch, seed: int):
        import jax
        import jax.numpy as jnp

        from readjax import sharding
        from readjax.training import TrainState, make_optimizer, make_train_step

        opt = make_optimizer(spec)
        params = jax.tree.map(jnp.copy, params)  # the step donates its state
        self.state = jax.device_put(TrainState(step=jnp.zeros((), jnp.int32), params=params,
                                               opt_state=opt.init(params)), sharding.replicated())
        self.batch = sharding.shard_batch(batch)
        self.fn = make_train_step(loss_fn, opt, jax.random.key(seed))

    def __call__(self):
        self.state, metrics = self.fn(self.state, self.batch)
        return metrics["loss"]

    def cost(self) -> dict:
        ca = self.fn.lower(self.state, self.batch).compile().cost_analysis()
        ca = ca[0] if isinstance(ca, list) else ca
        return {"gflop": round(ca.get("flops", 0.0) / 1e9, 3), "gb_accessed": round(ca.get("bytes accessed", 0.0) / 1e9, 3)}


def build(preset: str, batch: int, n_demos: int = 256):
    """READ's modules at a preset with random parameters, its two train steps and their inputs."""
    import jax
    import numpy as np

    from readjax import config, retrieval, tasks
    from readjax.diffusion import latent as latent_lib
    from readjax.methods import base
    from readjax.methods import read as read_lib
    from readjax.sim.camera import camera_from_model
    from readjax.training import StageSpec

    configs = config.presets(preset)
    train_cfg = configs["train"]
    size = configs["denoiser"].image_size
    env = tasks.make("reach_target")
    cam = camera_from_model(env.mj_model, "front", size, size)
    ds = synthetic_dataset(cam, n_demos, size)
    configs = read_lib.with_motion_stats(configs, ds.motion)
    ae, den = read_lib.build_modules(configs, env.chain, cam)
    k_ae, k_den = jax.random.split(jax.random.key(0))
    ae_params, den_params = read_lib.init_ae(ae, k_ae), read_lib.init_denoiser(den, size, k_den)
    latent = latent_lib.measure(ae, ae_params, ds.motion) if configs["sde"].latent_norm else None
    codes = latent_lib.codes(ae, ae_params, ds.motion, latent)
    dspec = StageSpec(steps=1, batch_size=batch, lr=train_cfg.lr, seed=1)
    vspec = StageSpec(steps=1, batch_size=batch, lr=train_cfg.vae_lr, seed=0)
    pairs = retrieval.training_pairs(cam, ds.motion, min(train_cfg.K, n_demos - 1), clamp=True)
    batch_fn = base.paired_batch(ds, dspec, pairs, n_demos, codes=codes)

    def read_step(sde):
        loss = read_lib.read_loss(ae, ae_params, den, sde, train_cfg.augment, configs["vae"].loss_weights, latent)
        return _Stepper(loss, den_params, dspec, first, 1)

    idx = np.arange(batch) % n_demos
    first = batch_fn(0)
    read = read_step(configs["sde"])
    return {
        "configs": configs, "ae": ae, "ae_params": ae_params, "den": den, "den_params": den_params,
        "latent": latent, "batch_fn": batch_fn, "batch": first, "read": read,
        # the paper's loss; the preset's own step where that is what the preset trains (not compiled twice)
        "read_plain": read_step(dataclasses.replace(configs["sde"], self_feed=0.0)) if configs["sde"].self_feed
        else read,
        "vae": _Stepper(read_lib.ae_loss(ae), ae_params, vspec,
                        {"motion": ds.motion[idx], "joints": ds.joints[idx]}, 0),
    }


def time_parts(b: dict, repeats: int) -> dict:
    """ms of each piece of the denoiser's step, timed alone (see the module docstring)."""
    import jax
    import jax.numpy as jnp
    import optax

    from readjax import sharding
    from readjax.diffusion import latent as latent_lib
    from readjax.methods.augment import augment_rgb
    from readjax.training import make_optimizer, StageSpec

    den, p, key = b["den"], b["den_params"], jax.random.key(0)
    image, motion = jnp.asarray(b["batch"]["image"]), jnp.asarray(b["batch"]["motion"])
    t = jnp.full((motion.shape[0],), 0.5)
    _, dec = latent_lib.codec(b["ae"], b["ae_params"], b["latent"])
    code = jnp.asarray(b["batch"]["code"])
    trunk = jax.jit(lambda p, x: den.apply(p, x, True, method="encode_image", rngs={"dropout": key}))
    trunk_grad = jax.jit(jax.grad(lambda p, x: jnp.sum(
        den.apply(p, x, True, method="encode_image", rngs={"dropout": key}) ** 2)))
    feats = trunk(p, image)
    denoise = jax.jit(lambda p, f: den.apply(p, f, motion, t, method="denoise"))
    denoise_grad = jax.jit(jax.grad(lambda p, f: jnp.sum(den.apply(p, f, motion, t, method="denoise") ** 2),
                                    argnums=(0, 1)))
    opt = make_optimizer(StageSpec(steps=1, batch_size=1))
    grads, opt_state = jax.tree.map(jnp.ones_like, p), opt.init(p)
    update = jax.jit(lambda g, s, p: optax.apply_updates(p, opt.update(g, s, p)[0]))
    decode = jax.jit(dec)
    augment = jax.jit(lambda x: augment_rgb(key, x))
    fns = {
        "host_batch_ms": lambda: sharding.shard_batch(b["batch_fn"](3)),
        "ae_decode_ms": lambda: decode(code),
        "augment_ms": lambda: augment(image),
        "unet_trunk_fwd_ms": lambda: trunk(p, image),
        "unet_trunk_fwd_bwd_ms": lambda: trunk_grad(p, image),
        "denoiser_fwd_ms": lambda: denoise(p, feats),
        "denoiser_fwd_bwd_ms": lambda: denoise_grad(p, feats),
        "adam_update_ms": lambda: update(grads, opt_state, p),
    }
    return {name: _median_ms(fn, repeats) for name, fn in fns.items()}


def _part_of(op_name: str, parts=PROFILE_PARTS) -> str:
    for part, keys in parts:
        if any(k in op_name for k in keys):
            return part
    return "other (loss, optimizer, glue)"


def profile_step(stepper: _Stepper, calls: int = 5, parts=PROFILE_PARTS) -> list[dict]:
    """ms per step of each model part (forward / backward), from a ``jax.profiler`` trace of
    ``calls`` steps: every executed XLA op is matched by name to the compiled program's metadata
    (``op_name``, which holds the flax module path; ``transpose(...)`` marks the backward pass).
    Empty where the backend records no per-op events."""
    import jax

    meta = {}
    for line in stepper.fn.lower(stepper.state, stepper.batch).compile().as_text().splitlines():
        m = re.match(r'\s*(?:ROOT )?%?([\w.\-]+) = .*?op_name="([^"]*)"', line)
        if m:
            meta[m.group(1)] = m.group(2)
    for _ in range(2):
        jax.block_until_ready(stepper())
    with tempfile.TemporaryDirectory() as d:
        jax.profiler.start_trace(d, create_perfetto_trace=True)
        for _ in range(calls):
            jax.block_until_ready(stepper())
        jax.profiler.stop_trace()
        files = sorted(glob.glob(f"{d}/**/*.json.gz", recursive=True))
        if not files:
            return []
        events = json.load(gzip.open(files[-1]))
    events = events["traceEvents"] if isinstance(events, dict) else events
    ms = collections.Counter()
    for e in events:
        name = e.get("name")
        if e.get("ph") == "X" and name in meta:
            direction = "bwd" if "transpose(" in meta[name] else "fwd"
            ms[(_part_of(meta[name], parts), direction)] += e.get("dur", 0) / 1e3 / calls
    found = sorted({p for p, _ in ms}, key=lambda p: -(ms[(p, "fwd")] + ms[(p, "bwd")]))
    return [{"part": p, "fwd_ms": round(ms[(p, "fwd")], 2), "bwd_ms": round(ms[(p, "bwd")], 2)} for p in found]


def bench_train(args) -> dict:
    """The benchmark's result (see the module docstring) for each preset in ``args.presets``."""
    import jax

    from readjax import provenance

    result = {"versions": provenance.versions(), "machine": provenance.machine(),
              "xla_flags": os.environ.get("XLA_FLAGS", ""), "devices": jax.device_count(), "parts": [],
              "profile": []}
    for preset in args.presets:
        t0 = time.perf_counter()
        b = build(preset, args.batch)
        read_ms = _median_ms(b["read"], args.repeats)
        row = {"preset": preset, "batch": args.batch, "read_step_ms": read_ms,
               "vae_step_ms": _median_ms(b["vae"], args.repeats),
               "read_plain_step_ms": read_ms if b["read_plain"] is b["read"] else _median_ms(b["read_plain"],
                                                                                          args.repeats)}
        row.update(time_parts(b, args.repeats))
        row["flops"] = {"read_step": b["read"].cost(), "vae_step": b["vae"].cost()}
        row["seconds"] = round(time.perf_counter() - t0, 1)
        result["parts"].append(row)
        pieces = ", ".join(f"{k[:-3]} {v:.1f}" for k, v in row.items() if k.endswith("_ms") and "step" not in k)
        print(f"{preset} B={args.batch}: READ step {row['read_step_ms']:.1f} ms (self_feed "
              f"{b['configs']['sde'].self_feed:g}; on the paper's loss {row['read_plain_step_ms']:.1f}), "
              f"autoencoder step {row['vae_step_ms']:.1f} ms; {pieces}", flush=True)
        if args.profile:
            for stage, parts in (("read", PROFILE_PARTS), ("vae", VAE_PROFILE_PARTS)):
                prof = profile_step(b[stage], parts=parts)
                result["profile"].append({"preset": preset, "batch": args.batch, "stage": stage, "parts": prof})
                total = sum(r["fwd_ms"] + r["bwd_ms"] for r in prof) or 1.0
                print(f"  {stage} step, ms by part (traced ops):", flush=True)
                for r in prof:
                    share = 100 * (r["fwd_ms"] + r["bwd_ms"]) / total
                    print(f"    {r['part']:32s} fwd {r['fwd_ms']:7.1f}  bwd {r['bwd_ms']:7.1f}  ({share:4.1f} %)",
                          flush=True)
    return result
