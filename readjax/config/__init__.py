"""Every configuration of readjax: typed, frozen sections, the two presets and the override parser
(METHOD.md sections 4-6, 9, 10).

Three dataclasses describe the learnable parts and the forward SDE (``sections``):

* :class:`VAEConfig` — the motion autoencoder (section 4), paper-style or kinematics-aware;
* :class:`DenoiserConfig` — ConvNeXt UNet image encoder + READ transformer (section 6);
* :class:`SDEConfig` — the mean-reverting SDE (section 5; Table 7's L and T);

and :class:`TrainConfig` the optimisation settings of every method. The baselines and variants of
section 10 add their own sections (``baselines``): :class:`ResNetConfig` (``resnet``,
Deterministic), :class:`VPSDEConfig` (``vpsde``, VPSDE and VPSDE+CG) and :class:`ReadOConfig`
(``read_o``); READ-L uses READ's three. ``METHOD_SECTIONS`` names them: a run records only the
sections its method uses (READ's runs: vae, denoiser, sde).

Module ``presets``: ``preset(name)`` returns ``{"vae": ..., "denoiser": ..., "sde": ...,
"resnet": ..., ...}`` for ``"paper"`` (the paper's sizes, meant for a GPU) or ``"cpu"`` (small
enough for a 2-core CPU: a batch-32 train step well under 0.3 s); ``presets(name)`` adds the
``"train"`` section; ``preset_names()`` lists them (the CLIs' ``--preset`` choices). Module
``parse``: :func:`override` applies ``"key=value"`` strings (from a CLI) to such a dict;
:func:`to_dict` / :func:`from_dict` round-trip it through JSON for checkpoints,
:func:`configs_to_dict` / :func:`configs_from_dict` a run's configs for ``run.json``.

The configs are frozen and hashable, so modules built from them can be static arguments of
``jax.jit``.
"""

from readjax.config.baselines import READ_O_SAMPLERS, VPSDE_SAMPLERS, ReadOConfig, ResNetConfig, VPSDEConfig
from readjax.config.parse import (ALIASES, configs_from_dict, configs_to_dict, field_defaults, from_dict, override,
                                  to_dict, without_inference_only)
from readjax.config.presets import METHOD_SECTIONS, SECTIONS, TRAIN_PRESETS, preset, preset_names, presets
from readjax.config.sections import (DEFAULT_N, INFERENCE_ONLY, REFINE_UPDATES, DenoiserConfig, SDEConfig, TrainConfig,
                                     VAEConfig)

__all__ = [
    "ALIASES", "DEFAULT_N", "INFERENCE_ONLY", "METHOD_SECTIONS", "READ_O_SAMPLERS", "REFINE_UPDATES", "SECTIONS",
    "TRAIN_PRESETS", "VPSDE_SAMPLERS", "DenoiserConfig", "ReadOConfig", "ResNetConfig", "SDEConfig",
    "TrainConfig", "VAEConfig", "VPSDEConfig", "configs_from_dict", "configs_to_dict", "field_defaults", "from_dict",
    "override", "preset", "preset_names", "presets", "to_dict", "without_inference_only",
]
