"""The sections of METHOD.md section 10's baselines and variants (``METHOD_SECTIONS``):
:class:`ResNetConfig` (``resnet``, Deterministic), :class:`VPSDEConfig` (``vpsde``, VPSDE and
VPSDE+CG) and :class:`ReadOConfig` (``read_o``); READ-L uses READ's sections."""

from __future__ import annotations

from dataclasses import dataclass

from readjax.config.sections import DEFAULT_N, _positive


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
    sample_steps: int = DEFAULT_N
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
