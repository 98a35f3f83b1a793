"""Typed, frozen model configurations and the two size presets (METHOD.md sections 4-6, 9).

Three dataclasses describe the learnable parts and the forward SDE:

* :class:`VAEConfig` — the motion autoencoder (section 4), paper-style or kinematics-aware;
* :class:`DenoiserConfig` — ConvNeXt UNet image encoder + READ transformer (section 6);
* :class:`SDEConfig` — the mean-reverting SDE (section 5; Table 7's L and T).

The baselines and variants of section 10 add their own sections: :class:`ResNetConfig`
(``resnet``, Deterministic), :class:`VPSDEConfig` (``vpsde``, VPSDE and VPSDE+CG) and
:class:`ReadOConfig` (``read_o``); READ-L uses READ's three. ``METHOD_SECTIONS`` names them: a
run records only the sections its method uses (READ's runs: vae, denoiser, sde).

``preset(name)`` returns ``{"vae": ..., "denoiser": ..., "sde": ..., "resnet": ..., ...}`` for ``"paper"`` (the
paper's sizes, meant for a GPU) or ``"cpu"`` (small enough for a 2-core CPU: a batch-32 train step
well under 0.3 s). :func:`override` applies ``"key=value"`` strings (from a CLI) to such a dict;
:func:`to_dict` / :func:`from_dict` round-trip it through JSON for checkpoints.

The configs are frozen and hashable, so modules built from them can be static arguments of
``jax.jit``.
"""

from __future__ import annotations

import dataclasses
import types
import typing
from dataclasses import dataclass
from typing import Any, Iterable, Mapping


def _positive(cfg, *names: str) -> None:
    for n in names:
        v = getattr(cfg, n)
        if not isinstance(v, int) or v <= 0:
            raise ValueError(f"{type(cfg).__name__}.{n} must be a positive int, got {v!r}")


@dataclass(frozen=True)
class VAEConfig:
    """The motion autoencoder (METHOD.md section 4).

    ``width`` is the transformer's model dimension; the paper ties it to ``latent_dim`` (32). When
    the two differ, a linear map joins them. ``ffn`` is the feed-forward width (the released code's
    default, 1024, also at width 32). ``kinematic`` selects the [beyond] joint-space decoder with
    differentiable forward kinematics; ``w_joint`` weighs its joint-space MSE and ``joint_margin``
    (radians) keeps decoded angles strictly inside the joint limits.
    """

    width: int = 32
    layers: int = 4
    heads: int = 4
    ffn: int = 1024
    latent_dim: int = 32
    kl_weight: float = 0.01
    kinematic: bool = False
    w_uv: float = 10.0
    w_z: float = 100.0  # z is in metres: 1 cm of depth weighs like ~1 px of uv at 64 px (see docs)
    w_rot6d: float = 1.0
    w_grip: float = 1.0
    w_joint: float = 1.0
    joint_margin: float = 1e-3

    def __post_init__(self):
        _positive(self, "width", "layers", "heads", "ffn", "latent_dim")
        if self.width % self.heads:
            raise ValueError(f"VAEConfig.width ({self.width}) must be divisible by heads ({self.heads})")
        if self.width % 2:
            raise ValueError("VAEConfig.width must be even (sinusoidal positions, half-width heads)")
        if self.kl_weight < 0 or self.joint_margin < 0:
            raise ValueError("VAEConfig.kl_weight and joint_margin must be >= 0")

    @property
    def loss_weights(self) -> dict[str, float]:
        """Weights of the per-key task-space MSEs, keyed like ``readjax.data.motion.KEYS``."""
        return {"uv": self.w_uv, "z": self.w_z, "rot6d": self.w_rot6d, "grip": self.w_grip}


@dataclass(frozen=True)
class DenoiserConfig:
    """The READ denoiser (METHOD.md section 6): ConvNeXt UNet + transformer over 203 tokens.

    ``normalize_motion``: the transformer embeds motions per-channel standardised and its delta
    heads predict in those units (``motion_mean``/``motion_std``, 10 values each, measured on the
    training set when training starts and recorded with the run; empty = raw units). Without it a
    channel with a small spread in metres (z: a few cm of depth) is nearly invisible to the
    embedding and is not learnt at the cpu preset's size (beyond the paper, see README).

    ``input_skip``: each image token also gets the input RGB-D itself, bilinearly sampled at the
    token's uv (depth converted to metres, standardised like z when motion stats exist). The UNet's
    features live on a stride-4 grid behind LayerNorms, which blur and re-scale the depth of a
    small object; the skip gives the transformer the exact depth under the motion (beyond the
    paper, see README). The per-image cache then carries the input pixels (space-to-depth) after
    the trunk features: ``cache_channels``.

    ``conv_dims``/``enc_depths`` are the four encoder stages, ``dec_depths`` the three decoder
    levels (deepest first is level 2; tuples are ordered from the shallowest level, like the
    encoder's). ``feature_channels`` is C of the full-resolution feature map; when it differs from
    ``d_model`` a linear map projects the sampled image tokens. ``image_size`` must be a multiple
    of 32 (stride 4 stem, then three stride-2 stages).
    """

    image_size: int = 256
    in_channels: int = 4
    conv_dims: tuple[int, ...] = (96, 192, 384, 768)
    enc_depths: tuple[int, ...] = (3, 3, 9, 3)
    dec_depths: tuple[int, ...] = (3, 3, 3)
    drop_path: float = 0.1
    layer_scale_init: float = 1e-6
    feature_channels: int = 128
    d_model: int = 128
    layers: int = 8
    heads: int = 4
    ffn: int = 1024
    normalize_motion: bool = False
    input_skip: bool = False
    motion_mean: tuple[float, ...] = ()
    motion_std: tuple[float, ...] = ()

    @property
    def cache_channels(self) -> int:
        """Channels of the per-image cache (``Denoiser.encode_image``)."""
        return self.conv_dims[0] + (16 * self.in_channels if self.input_skip else 0)

    def __post_init__(self):
        _positive(self, "image_size", "in_channels", "feature_channels", "d_model", "layers", "heads", "ffn")
        if len(self.motion_mean) != len(self.motion_std) or len(self.motion_std) not in (0, 10):
            raise ValueError("DenoiserConfig.motion_mean and motion_std must both be empty or hold 10 values")
        if any(not s > 0 for s in self.motion_std):
            raise ValueError(f"DenoiserConfig.motion_std must be > 0, got {self.motion_std}")
        if len(self.conv_dims) != 4 or len(self.enc_depths) != 4 or len(self.dec_depths) != 3:
            raise ValueError("DenoiserConfig needs 4 conv_dims, 4 enc_depths and 3 dec_depths, got "
                             f"{self.conv_dims}, {self.enc_depths}, {self.dec_depths}")
        if min(self.conv_dims) <= 0 or min(self.enc_depths) < 0 or min(self.dec_depths) < 0:
            raise ValueError("DenoiserConfig conv_dims must be > 0 and depths >= 0")
        if any(d % 2 for d in self.conv_dims[1:]):
            raise ValueError("DenoiserConfig conv_dims[1:] must be even (the decoder halves them)")
        if self.image_size % 32:
            raise ValueError(f"DenoiserConfig.image_size must be a multiple of 32, got {self.image_size}")
        if self.d_model % self.heads or self.d_model % 4:
            raise ValueError(f"DenoiserConfig.d_model ({self.d_model}) must be divisible by heads "
                             f"({self.heads}) and by 4")
        if not 0.0 <= self.drop_path < 1.0:
            raise ValueError("DenoiserConfig.drop_path must be in [0, 1)")


REFINE_UPDATES = ("renoise", "cold", "cold_anchor")


@dataclass(frozen=True)
class SDEConfig:
    """The mean-reverting SDE of METHOD.md section 5.

    ``lam`` is Table 7's L (stationary noise level), ``theta1`` its T (end of the linear theta
    schedule). ``theta0=None`` means theta0 = lam, the released code's quirk kept as the default.
    ``t_min`` is the smallest training time. ``update`` is READ's refinement step at inference
    (``readjax.diffusion.refine``): "renoise" re-noises the prediction to the next time (the paper,
    METHOD.md section 8), "cold" moves the latent by the change of the degradation between the two
    times (the improved cold-diffusion update of Bansal et al.; deterministic), "cold_anchor" does
    the same after a first step that anchors the latent at the degradation of the first prediction
    (the paper's first step without its noise). Inference only: a trained run can be evaluated with
    any of them.

    ``latent_norm`` (the latent methods, READ and READ-L): the SDE runs on the autoencoder's latent
    standardised per dimension with the training set's mean and std (measured once the autoencoder
    is trained, ``readjax.diffusion.latent``), so that ``lam`` is a noise level in units of the
    data's own spread in every dimension. False is the paper's raw latent (the dataclass default,
    so runs recorded before the field existed keep their meaning); the presets turn it on: on a raw
    latent whose dimensions spread by 0.03-1.3, lam = 0.5 buries most of them (beyond the paper,
    see README).
    """

    lam: float = 0.5
    theta1: float = 2.0
    theta0: float | None = None
    t_min: float = 1e-5
    update: str = "renoise"
    latent_norm: bool = False

    def __post_init__(self):
        if self.lam <= 0:
            raise ValueError(f"SDEConfig.lam must be > 0, got {self.lam}")
        if not 0.0 < self.t_min < 1.0:
            raise ValueError(f"SDEConfig.t_min must be in (0, 1), got {self.t_min}")
        if self.theta_start < 0 or self.theta1 < 0 or self.theta_start + self.theta1 <= 0:
            raise ValueError("SDEConfig theta0 and theta1 must be >= 0 and not both 0")
        if self.update not in REFINE_UPDATES:
            raise ValueError(f"SDEConfig.update must be one of {', '.join(REFINE_UPDATES)}, got {self.update!r}")

    @property
    def theta_start(self) -> float:
        """theta(0): ``theta0`` if given, else ``lam``."""
        return self.lam if self.theta0 is None else float(self.theta0)


@dataclass(frozen=True)
class ResNetConfig:
    """The Deterministic baseline (METHOD.md section 10): ResNet18 trunk -> per-location linear ->
    flatten -> per-key two-layer GELU MLP -> motion.

    ``stage_widths``/``stage_blocks`` are the four residual stages (ResNet18: 64/128/256/512 and
    2/2/2/2 basic blocks; the stem is a 7x7 stride-2 conv to ``stage_widths[0]`` and a 3x3 stride-2
    max-pool, so the feature map is ``input_size / 32`` wide). Norms are GroupNorm with
    ``norm_groups`` groups (the released code's timm ResNet uses BatchNorm). ``proj_dim`` is the
    per-location linear 512 -> 256; ``head_hidden`` the per-key MLP's hidden width, 0 = half the
    flattened feature size (the released code's choice).
    """

    input_size: int = 256
    stage_widths: tuple[int, ...] = (64, 128, 256, 512)
    stage_blocks: tuple[int, ...] = (2, 2, 2, 2)
    norm_groups: int = 32
    proj_dim: int = 256
    head_hidden: int = 0

    def __post_init__(self):
        _positive(self, "input_size", "norm_groups", "proj_dim")
        if len(self.stage_widths) != 4 or len(self.stage_blocks) != 4:
            raise ValueError(f"ResNetConfig needs 4 stage_widths and 4 stage_blocks, got {self.stage_widths}, "
                             f"{self.stage_blocks}")
        if min(self.stage_widths) <= 0 or min(self.stage_blocks) <= 0:
            raise ValueError("ResNetConfig stage_widths and stage_blocks must be > 0")
        if any(w % self.norm_groups for w in self.stage_widths):
            raise ValueError(f"ResNetConfig.stage_widths {self.stage_widths} must be divisible by norm_groups "
                             f"({self.norm_groups})")
        if self.input_size % 32:
            raise ValueError(f"ResNetConfig.input_size must be a multiple of 32, got {self.input_size}")
        if not isinstance(self.head_hidden, int) or self.head_hidden < 0:
            raise ValueError(f"ResNetConfig.head_hidden must be an int >= 0, got {self.head_hidden!r}")

    @property
    def flat_dim(self) -> int:
        """Size of the flattened projected feature map."""
        return (self.input_size // 32) ** 2 * self.proj_dim

    @property
    def hidden(self) -> int:
        return self.head_hidden or max(self.flat_dim // 2, 1)


VPSDE_SAMPLERS = ("ode", "sde")


@dataclass(frozen=True)
class VPSDEConfig:
    """The VPSDE and VPSDE+CG baselines (METHOD.md section 10, supplement section 7).

    dx = -1/2 beta(t) x dt + sqrt(beta(t)) dw with beta linear from ``beta_min`` (t = 0) to
    ``beta_max`` (t = 1) on per-dimension normalised motions. Training times t ~ U(train_eps, 1);
    sampling runs ``sample_steps`` Euler steps (the default N) from t = 1 to ``sample_eps`` with
    ``sampler`` "ode" (probability flow) or "sde" (reverse SDE, Euler-Maruyama). VPSDE+CG:
    ``guidance`` is w in eps = w eps(cond) - (w - 1) eps(uncond); ``cond_drop`` the probability of
    masking the retrieved motion in training.
    """

    beta_min: float = 1.0
    beta_max: float = 20.0
    train_eps: float = 1e-5
    sample_eps: float = 1e-3
    sampler: str = "ode"
    sample_steps: int = 100
    guidance: float = 1.0
    cond_drop: float = 0.1

    def __post_init__(self):
        _positive(self, "sample_steps")
        if not 0 < self.beta_min <= self.beta_max:
            raise ValueError(f"VPSDEConfig needs 0 < beta_min <= beta_max, got {self.beta_min}, {self.beta_max}")
        if not 0.0 < self.train_eps < 1.0 or not 0.0 < self.sample_eps < 1.0:
            raise ValueError("VPSDEConfig.train_eps and sample_eps must be in (0, 1)")
        if self.sampler not in VPSDE_SAMPLERS:
            raise ValueError(f"VPSDEConfig.sampler must be one of {VPSDE_SAMPLERS}, got {self.sampler!r}")
        if not 0.0 <= self.cond_drop < 1.0:
            raise ValueError(f"VPSDEConfig.cond_drop must be in [0, 1), got {self.cond_drop}")


READ_O_SAMPLERS = ("cd", "em")


@dataclass(frozen=True)
class ReadOConfig:
    """READ-O (METHOD.md section 10): READ's SDE (the ``sde`` section) in task space.

    ``sampler`` "cd": cold diffusion, the denoiser predicts x0 (output="delta") and is re-noised
    (METHOD.md section 8 without the autoencoder); "em": Euler-Maruyama on the reverse
    mean-reverting SDE with a noise-predicting denoiser (output="eps"). The sampler fixes the
    training target, so it is a training-time choice.
    """

    sampler: str = "cd"

    def __post_init__(self):
        if self.sampler not in READ_O_SAMPLERS:
            raise ValueError(f"ReadOConfig.sampler must be one of {READ_O_SAMPLERS}, got {self.sampler!r}")


SECTIONS = {"vae": VAEConfig, "denoiser": DenoiserConfig, "sde": SDEConfig,
            "resnet": ResNetConfig, "vpsde": VPSDEConfig, "read_o": ReadOConfig}
# Sections only some methods use (baselines, variants); READ's runs record only the others.
METHOD_SECTIONS = ("resnet", "vpsde", "read_o")
# Table 7's one-letter names for the SDE hyperparameters.
ALIASES = {"L": "sde.lam", "T": "sde.theta1"}

_PRESETS: dict[str, dict[str, Any]] = {
    "paper": {
        "vae": VAEConfig(),
        "denoiser": DenoiserConfig(),
        "sde": SDEConfig(latent_norm=True),
        "resnet": ResNetConfig(),
        "vpsde": VPSDEConfig(),
        "read_o": ReadOConfig(),
    },
    "cpu": {
        "vae": VAEConfig(width=32, layers=2, heads=4, ffn=128, latent_dim=32),
        # No ConvNeXt blocks at the 1/4-resolution level (it is patchify conv + skip only) and a
        # 2-layer, 2-head transformer: on a busy 2-core CPU a batch-32 READ step measured ~0.4
        # CPU-seconds; blocks at 1/4 resolution and 4 heads each added 0.05-0.1 s (see the report).
        "denoiser": DenoiserConfig(image_size=64, conv_dims=(16, 32, 64, 128), enc_depths=(0, 1, 1, 1),
                                   dec_depths=(0, 1, 1), drop_path=0.1, feature_channels=64, d_model=64,
                                   layers=2, heads=2, ffn=128),
        "sde": SDEConfig(latent_norm=True),
        # ResNet18 with a quarter of the channels at 64 px: a batch-32 step measured ~0.13 s here.
        "resnet": ResNetConfig(input_size=64, stage_widths=(16, 32, 64, 128), stage_blocks=(2, 2, 2, 2),
                               norm_groups=8, proj_dim=64, head_hidden=256),
        "vpsde": VPSDEConfig(),
        "read_o": ReadOConfig(),
    },
}


def preset_names() -> tuple[str, ...]:
    return tuple(_PRESETS)


def preset(name: str) -> dict[str, Any]:
    """``{"vae": VAEConfig, "denoiser": DenoiserConfig, "sde": SDEConfig, ...}`` of a named preset
    (every section of ``SECTIONS``)."""
    if name not in _PRESETS:
        raise ValueError(f"unknown preset {name!r}; known: {', '.join(_PRESETS)}")
    return dict(_PRESETS[name])


def _parse(text: str, tp, where: str):
    """Parse one value of annotated type ``tp`` from a string."""
    s = text.strip()
    origin = typing.get_origin(tp)
    args = typing.get_args(tp)
    if origin in (typing.Union, types.UnionType):
        if type(None) in args and s.lower() in ("none", "null"):
            return None
        inner = [a for a in args if a is not type(None)]
        return _parse(s, inner[0], where)
    if origin is tuple:
        elem = args[0] if args else int
        parts = [p for p in s.strip("()[] ").split(",") if p.strip()]
        return tuple(_parse(p, elem, where) for p in parts)
    if tp is bool:
        if s.lower() in ("1", "true", "yes", "on"):
            return True
        if s.lower() in ("0", "false", "no", "off"):
            return False
        raise ValueError(f"{where}: expected a boolean, got {text!r}")
    if tp is int:
        try:
            return int(s)
        except ValueError:
            raise ValueError(f"{where}: expected an int, got {text!r}") from None
    if tp is float:
        try:
            return float(s)
        except ValueError:
            raise ValueError(f"{where}: expected a float, got {text!r}") from None
    if tp is str:
        return s
    raise ValueError(f"{where}: cannot parse type {tp}")


def _resolve(key: str) -> tuple[str, str]:
    key = ALIASES.get(key.strip(), key.strip())
    if "." in key:
        section, field = key.split(".", 1)
        if section not in SECTIONS:
            raise ValueError(f"unknown config section {section!r} in {key!r}; known: {', '.join(SECTIONS)}")
        if field not in {f.name for f in dataclasses.fields(SECTIONS[section])}:
            raise ValueError(f"{SECTIONS[section].__name__} has no field {field!r}")
        return section, field
    owners = [s for s, cls in SECTIONS.items() if key in {f.name for f in dataclasses.fields(cls)}]
    if not owners:
        raise ValueError(f"unknown config field {key!r}")
    if len(owners) > 1:
        raise ValueError(f"config field {key!r} is ambiguous; write one of "
                         + ", ".join(f"{s}.{key}" for s in owners))
    return owners[0], key


def override(configs: Mapping[str, Any], items: Iterable[str]) -> dict[str, Any]:
    """Apply ``"key=value"`` overrides to a preset dict and return a new dict.

    Keys are ``section.field`` (``vae.width``, ``denoiser.conv_dims``), a field name that only one
    section has (``latent_dim``), or a Table 7 alias (``L``, ``T``). Tuples are comma-separated
    (``denoiser.enc_depths=1,1,2,1``); ``none`` sets an optional field to None. The configs'
    own validation runs on the result.
    """
    out = dict(configs)
    changes: dict[str, dict[str, Any]] = {}
    for item in items:
        if "=" not in item:
            raise ValueError(f"override {item!r} is not of the form key=value")
        key, value = item.split("=", 1)
        section, field = _resolve(key)
        hints = typing.get_type_hints(SECTIONS[section])
        changes.setdefault(section, {})[field] = _parse(value, hints[field], f"{section}.{field}")
    for section, kw in changes.items():
        if section not in out:
            raise ValueError(f"configs have no section {section!r}")
        out[section] = dataclasses.replace(out[section], **kw)
    return out


def to_dict(configs: Mapping[str, Any]) -> dict[str, dict[str, Any]]:
    """JSON-ready nested dict of a preset-style dict (tuples become lists)."""
    return {name: dataclasses.asdict(cfg) for name, cfg in configs.items()}


def from_dict(d: Mapping[str, Mapping[str, Any]]) -> dict[str, Any]:
    """Inverse of :func:`to_dict` (unknown sections are rejected, lists become tuples)."""
    out = {}
    for name, fields in d.items():
        if name not in SECTIONS:
            raise ValueError(f"unknown config section {name!r}")
        cls = SECTIONS[name]
        hints = typing.get_type_hints(cls)
        kw = {}
        for k, v in fields.items():
            if k not in hints:
                raise ValueError(f"{cls.__name__} has no field {k!r}")
            kw[k] = tuple(v) if isinstance(v, list) else v
        out[name] = cls(**kw)
    return out
