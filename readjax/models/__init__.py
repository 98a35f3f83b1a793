"""Flax (linen) modules of readjax: motion autoencoders, the ConvNeXt UNet and the READ denoiser.

* :mod:`readjax.models.vae` — the paper's transformer motion VAE and shared transformer blocks;
* :mod:`readjax.models.kinematic_vae` — [beyond] the kinematics-aware autoencoder and
  :func:`make_autoencoder`, the factory for both;
* :mod:`readjax.models.convnext_unet` — the image encoder (full-resolution feature map);
* :mod:`readjax.models.denoiser` — feature sampling at uv and the READ denoiser transformer;
* :mod:`readjax.models.latent_denoiser` — READ-L's latent-space denoiser;
* :mod:`readjax.models.resnet` — the Deterministic baseline (ResNet18 trunk + per-key MLPs).
"""

from readjax.models.convnext_unet import ConvNeXtUNet
from readjax.models.denoiser import Denoiser, sample_features
from readjax.models.kinematic_vae import KinematicAE, KinematicConstants, fk_motion, make_autoencoder
from readjax.models.latent_denoiser import LatentDenoiser
from readjax.models.resnet import DeterministicPlanner
from readjax.models.vae import MotionVAE

__all__ = [
    "ConvNeXtUNet",
    "Denoiser",
    "DeterministicPlanner",
    "KinematicAE",
    "KinematicConstants",
    "LatentDenoiser",
    "MotionVAE",
    "fk_motion",
    "make_autoencoder",
    "sample_features",
]
