"""READ's sections and the training section (METHOD.md sections 4-6): :class:`VAEConfig` (the
motion autoencoder), :class:`DenoiserConfig` (ConvNeXt UNet image encoder + READ transformer),
:class:`SDEConfig` (the mean-reverting SDE; Table 7's L and T) and :class:`TrainConfig`
(optimisation settings of every method)."""

from __future__ import annotations

from dataclasses import dataclass


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
        """Weights of the per-key task-space MSEs, keyed like ``readjax.motion.KEYS``."""
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

    ``surface_depth`` (needs ``input_skip``): each motion token's embedding also reads how far the
    frame lies beyond the visible surface under it, z - depth(uv), in the units of the standardised
    z (metres without motion stats). The READ transformer keeps motion and image tokens apart, so
    without it a motion token must find its own frame's image token by attention before it can
    compare its depth with the image's; with it, "end 28 mm behind the sphere's surface" is one
    linear read (beyond the paper, see README).

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
    surface_depth: bool = False
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
        if self.surface_depth and not self.input_skip:
            raise ValueError("DenoiserConfig.surface_depth reads the input depth under each frame: it needs "
                             "input_skip=True")


REFINE_UPDATES = ("renoise", "cold", "cold_anchor")
# Config fields that change inference only: a stage trained under one value serves every other, so a
# run's stages resume (and its identity check passes) whichever value a later preset sets.
INFERENCE_ONLY = {"sde": ("update", "rounds")}
SCHEDULES = ("staircase", "cosine")
DEFAULT_N = 100  # sampler / refinement steps when none are asked for (the paper's setting A)


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
    data's own spread in every dimension. False (the default, both presets) is the paper's raw
    code. Measured on reach_target it makes the denoiser's local corrections better but READ's
    executed success worse (BENCHMARKS.md section 8), so it stays an option.

    ``self_feed`` (READ, training only) is the fraction of each training batch whose noised latent
    is built from the denoiser's own prediction instead of from the ground truth: a first,
    gradient-free pass predicts M̂0 from the usual z_t, and the trained pass sees the degradation
    of Enc(M̂0) at the same t with the same noise. At inference every step after the first reads
    the degradation of the previous step's prediction, never the ground truth's; trained only on
    the latter, the map x -> D(Dec(Enc(x)), t) is not a contraction onto the answer, and N steps
    end further off than one (BENCHMARKS.md 13). 0 (the default) is the paper's objective.
    """

    lam: float = 0.5
    theta1: float = 2.0
    theta0: float | None = None
    t_min: float = 1e-5
    update: str = "renoise"
    latent_norm: bool = False
    # refinements in a row at inference, each started from the previous one's plan as its retrieved
    # motion (``Planner.refine``); 1 is the paper's single refinement
    rounds: int = 1
    self_feed: float = 0.0

    def __post_init__(self):
        if self.lam <= 0:
            raise ValueError(f"SDEConfig.lam must be > 0, got {self.lam}")
        if not 0.0 < self.t_min < 1.0:
            raise ValueError(f"SDEConfig.t_min must be in (0, 1), got {self.t_min}")
        if self.theta_start < 0 or self.theta1 < 0 or self.theta_start + self.theta1 <= 0:
            raise ValueError("SDEConfig theta0 and theta1 must be >= 0 and not both 0")
        if isinstance(self.rounds, bool) or not isinstance(self.rounds, int) or self.rounds < 1:
            raise ValueError(f"SDEConfig.rounds must be a positive int, got {self.rounds!r}")
        if not 0.0 <= self.self_feed <= 1.0:
            raise ValueError(f"SDEConfig.self_feed must be in [0, 1], got {self.self_feed!r}")
        if self.update not in REFINE_UPDATES:
            raise ValueError(f"SDEConfig.update must be one of {', '.join(REFINE_UPDATES)}, got {self.update!r}")

    @property
    def theta_start(self) -> float:
        """theta(0): ``theta0`` if given, else ``lam``."""
        return self.lam if self.theta0 is None else float(self.theta0)


@dataclass(frozen=True)
class TrainConfig:
    """Optimisation settings (METHOD.md sections 4 and 6). ``K`` is Table 7's neighbour pool."""

    episodes: int = 0  # training demos to use (0 = all in the dataset)
    vae_steps: int = 50_000
    vae_batch: int = 32
    vae_lr: float = 1e-4
    steps: int = 50_000  # the diffusion model / baseline
    batch: int = 64
    lr: float = 1e-4
    lr_decay: float = 0.99  # every lr_decay_every steps (staircase)
    lr_decay_every: int = 5000
    # "staircase": the network stage's lr times lr_decay every lr_decay_every steps, the
    # autoencoder's constant (the released code's). "cosine": each stage's lr decays along one
    # cosine to 0 over its own steps (vae_steps, steps), lr_decay* unused, so the checkpoint a
    # stage ends on is where the optimiser settled, not one point of a trajectory still moving at
    # full step size. At the cpu preset on RT it makes the autoencoder 4x more exact (end point
    # 25-33 -> 6-8 mm) yet READ's success fell (79 / 51 -> 57 / 41 %): off in both presets
    # (BENCHMARKS.md 8h)
    schedule: str = "staircase"
    K: int = 3
    augment: bool = True
    ckpt_every: int = 2000
    log_every: int = 50
    seed: int = 0
    # The convergence rule (every stage of every method): the last ``val_episodes`` demos of the
    # training split are held out (never the test seeds); every ``val_every`` steps the stage's
    # loss on them is measured (fixed batches and noise), and with ``stop_patience`` > 0 a stage
    # stops once its validation loss has not improved by more than ``stop_min_delta`` (relative)
    # over the last ``stop_patience`` steps; ``vae_steps`` / ``steps`` are then the caps. The stage
    # records when and why it stopped (``<stage>/stop.json``). 0 / 0: train every demo to the cap.
    val_episodes: int = 0
    val_every: int = 250
    stop_patience: int = 0
    stop_min_delta: float = 0.01

    def __post_init__(self):
        for n in ("vae_steps", "vae_batch", "steps", "batch", "K", "ckpt_every", "log_every", "val_every"):
            if not isinstance(getattr(self, n), int) or getattr(self, n) < 1:
                raise ValueError(f"TrainConfig.{n} must be a positive int, got {getattr(self, n)!r}")
        for n in ("val_episodes", "stop_patience"):
            if not isinstance(getattr(self, n), int) or getattr(self, n) < 0:
                raise ValueError(f"TrainConfig.{n} must be a non-negative int, got {getattr(self, n)!r}")
        if self.stop_patience and not self.val_episodes:
            raise ValueError("TrainConfig.stop_patience needs a validation split: set train.val_episodes > 0")
        if self.stop_patience and self.stop_patience < self.val_every:
            raise ValueError(f"TrainConfig.stop_patience ({self.stop_patience}) must span at least one validation "
                             f"(val_every = {self.val_every})")
        if not 0.0 <= self.stop_min_delta < 1.0:
            raise ValueError(f"TrainConfig.stop_min_delta must be in [0, 1), got {self.stop_min_delta!r}")
        if self.schedule not in SCHEDULES:
            raise ValueError(f"TrainConfig.schedule must be one of {', '.join(SCHEDULES)}, got {self.schedule!r}")
