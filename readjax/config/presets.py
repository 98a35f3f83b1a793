"""The sections a preset holds (``SECTIONS``) and the two presets: ``"paper"`` (the paper's
sizes, meant for a GPU) and ``"cpu"`` (small enough for a 2-core CPU: a batch-32 train step well
under 0.3 s). :func:`preset` gives a preset's model sections, :func:`presets` those and its
training section (``train``)."""

from __future__ import annotations

from typing import Any

from readjax.config.baselines import ReadOConfig, ResNetConfig, VPSDEConfig
from readjax.config.sections import DenoiserConfig, SDEConfig, TrainConfig, VAEConfig

SECTIONS = {"vae": VAEConfig, "denoiser": DenoiserConfig, "sde": SDEConfig,
            "resnet": ResNetConfig, "vpsde": VPSDEConfig, "read_o": ReadOConfig}
# Sections only some methods use (baselines, variants); READ's runs record only the others.
METHOD_SECTIONS = ("resnet", "vpsde", "read_o")

_PRESETS: dict[str, dict[str, Any]] = {
    "paper": {
        "vae": VAEConfig(),
        "denoiser": DenoiserConfig(),
        "sde": SDEConfig(),
        "resnet": ResNetConfig(),
        "vpsde": VPSDEConfig(),
        "read_o": ReadOConfig(),
    },
    "cpu": {
        # READ's departures at this scale (README "Where readjax departs from the paper";
        # measured on reach_target, BENCHMARKS.md 8c-8d): a weak KL (the autoencoder's end point
        # 3.9 -> 1.2 cm), the denoiser reads the exact RGB-D under each frame with motions
        # standardised (its depth corrections), it trains on its K = 50 nearest neighbours
        # (SPE's starts are ~5-10 cm off; the 3 nearest are 2-4 cm), and refinement takes the
        # improved cold-diffusion step (the paper's re-noising walks away from the answer) after a
        # first step anchored at the degraded prediction ("cold_anchor": started at zR, the cold
        # steps never apply the part a(1) = 0.29 of the correction; anchored, three RT trainings
        # gained +4 / +4 / +5 episodes and lost none, BENCHMARKS.md 8l), in two rounds (the second
        # refines the first's plan: the denoiser corrects a near start better than a far one; +5 / +6
        # / +3 episodes more, none lost; RT 82 / 61 / 72 -> 91 / 71 / 80 % over the three trainings).
        # Half of each denoiser batch is trained on the degradation of its own gradient-free
        # prediction (``sde.self_feed``): the loop feeds it nothing else from its second step on, and
        # without it refinement walks away from a correct answer on training images (the refinement
        # issue's check; BENCHMARKS.md 18i-18j). ``--set sde.self_feed=0`` trains the earlier recipe.
        "vae": VAEConfig(width=32, layers=2, heads=4, ffn=128, latent_dim=32, kl_weight=1e-4),
        # No ConvNeXt blocks at the 1/4-resolution level (it is patchify conv + skip only) and a
        # 2-layer, 2-head transformer: on a busy 2-core CPU a batch-32 READ step measured ~0.4
        # CPU-seconds; blocks at 1/4 resolution and 4 heads each added 0.05-0.1 s (see the report).
        "denoiser": DenoiserConfig(image_size=64, conv_dims=(16, 32, 64, 128), enc_depths=(0, 1, 1, 1),
                                   dec_depths=(0, 1, 1), drop_path=0.1, feature_channels=64, d_model=64,
                                   layers=2, heads=2, ffn=128, normalize_motion=True, input_skip=True),
        "sde": SDEConfig(update="cold_anchor", rounds=2, self_feed=0.5),
        # ResNet18 with a quarter of the channels at 64 px: a batch-32 step measured ~0.13 s here.
        "resnet": ResNetConfig(input_size=64, stage_widths=(16, 32, 64, 128), stage_blocks=(2, 2, 2, 2),
                               norm_groups=8, proj_dim=64, head_hidden=256),
        "vpsde": VPSDEConfig(),
        "read_o": ReadOConfig(),
    },
}

TRAIN_PRESETS = {
    "paper": TrainConfig(),
    # 5000 network steps (the lr halved at 1500 / 3000 / 4500): on RT four trainings of READ's
    # denoiser each gained over 3000 steps (+2 to +11 points at N = 100, mean 72 % over three seeds
    # against 67 %; BENCHMARKS 8f, 8j). The autoencoder keeps 3000 steps.
    "cpu": TrainConfig(vae_steps=3000, vae_batch=32, vae_lr=1e-3, steps=5000, batch=32, lr=3e-4,
                       lr_decay=0.5, lr_decay_every=1500, ckpt_every=500, log_every=25, K=50),
}


def preset_names() -> tuple[str, ...]:
    return tuple(_PRESETS)


def preset(name: str) -> dict[str, Any]:
    """``{"vae": VAEConfig, "denoiser": DenoiserConfig, "sde": SDEConfig, ...}`` of a named preset
    (every section of ``SECTIONS``)."""
    if name not in _PRESETS:
        raise ValueError(f"unknown preset {name!r}; known: {', '.join(_PRESETS)}")
    return dict(_PRESETS[name])


def presets(name: str) -> dict[str, Any]:
    """All configs of a preset: vae, denoiser, sde (READ), resnet, vpsde, read_o (baselines and
    variants, ``config.METHOD_SECTIONS``) and train."""
    if name not in TRAIN_PRESETS:
        raise ValueError(f"unknown preset {name!r}; known: {', '.join(TRAIN_PRESETS)}")
    return dict(preset(name), train=TRAIN_PRESETS[name])
