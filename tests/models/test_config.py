"""Model configs: presets, key=value overrides, JSON round trip, validation."""

import json

import pytest

from readjax import config
from readjax.config import DenoiserConfig, SDEConfig, VAEConfig


def test_presets():
    assert set(config.preset_names()) >= {"paper", "cpu"}
    paper = config.preset("paper")
    assert paper["vae"] == VAEConfig(width=32, layers=4, heads=4, latent_dim=32, kl_weight=0.01)
    d = paper["denoiser"]
    assert (d.conv_dims, d.enc_depths, d.dec_depths) == ((96, 192, 384, 768), (3, 3, 9, 3), (3, 3, 3))
    sizes = (d.feature_channels, d.d_model, d.layers, d.heads, d.ffn, d.image_size)
    assert sizes == (128, 128, 8, 4, 1024, 256)
    assert d.drop_path == 0.1
    # the paper's SDE on the raw code (sde.latent_norm, readjax.diffusion.latent, is an option)
    assert paper["sde"] == SDEConfig(lam=0.5, theta1=2.0, theta0=None, t_min=1e-5, latent_norm=False)
    assert not config.preset("cpu")["sde"].latent_norm
    # the paper preset is the paper; the cpu preset departs in exactly five settings (README)
    full = config.presets("paper")
    assert (full["vae"].kl_weight, full["train"].K, full["sde"].update) == (0.01, 3, "renoise")
    assert not (full["denoiser"].input_skip or full["denoiser"].normalize_motion)
    cpu = config.presets("cpu")
    assert (cpu["vae"].kl_weight, cpu["train"].K, cpu["sde"].update) == (1e-4, 50, "cold_anchor")
    assert (full["sde"].rounds, cpu["sde"].rounds) == (1, 2)
    assert cpu["denoiser"].input_skip and cpu["denoiser"].normalize_motion
    assert config.preset("cpu")["denoiser"].image_size == 64
    with pytest.raises(ValueError, match="unknown preset"):
        config.preset("tpu")
    # presets are hashable (modules built from them can be jit static arguments)
    hash(tuple(paper.values()))


def test_override():
    cfgs = config.override(config.preset("cpu"), [
        "vae.width=64", "denoiser.conv_dims=8,16,32,64", "kinematic=true", "L=0.3", "T=4", "sde.theta0=none",
        "latent_dim=16", "drop_path=0", "sde.theta0=0.2",
    ])
    assert cfgs["vae"].width == 64 and cfgs["vae"].kinematic is True and cfgs["vae"].latent_dim == 16
    assert cfgs["denoiser"].conv_dims == (8, 16, 32, 64) and cfgs["denoiser"].drop_path == 0.0
    assert cfgs["sde"].lam == 0.3 and cfgs["sde"].theta1 == 4.0 and cfgs["sde"].theta0 == 0.2
    assert config.override(config.preset("cpu"), ["sde.theta0=None"])["sde"].theta0 is None
    assert config.preset("cpu")["vae"].width == 32  # presets are not mutated
    for bad, match in [("layers=3", "ambiguous"), ("vae.depth=3", "no field"), ("foo.bar=1", "section"),
                       ("width", "key=value"), ("vae.width=wide", "int"), ("vae.kinematic=maybe", "boolean"),
                       ("vae.heads=5", "divisible")]:
        with pytest.raises(ValueError, match=match):
            config.override(config.preset("cpu"), [bad])


def test_override_train():
    """With a ``train`` section (``presets``), train.* keys and bare train field names no model section
    has set it; without one, such keys are left to the model sections (and rejected there)."""
    cfgs = config.override(config.presets("cpu"), ["train.steps=5", "K=4", "augment=no", "lr=1e-3", "vae.width=64"])
    assert (cfgs["train"].steps, cfgs["train"].K, cfgs["train"].augment, cfgs["train"].lr) == (5, 4, False, 1e-3)
    assert cfgs["vae"].width == 64 and config.presets("cpu")["train"].steps == 5000
    assert set(config.presets("paper")) == set(config.SECTIONS) | {"train"}
    for bad, match in [("train.foo=1", "TrainConfig has no field"), ("episodes=x", "expected int"),
                       ("augment= true", "boolean"), ("train.K=0", "positive"), ("steps", "key=value")]:
        with pytest.raises(ValueError, match=match):
            config.override(config.presets("cpu"), [bad])
    for bad, match in [("train.steps=5", "unknown config section 'train'"), ("steps=5", "unknown config field")]:
        with pytest.raises(ValueError, match=match):
            config.override(config.preset("cpu"), [bad])
    with pytest.raises(ValueError, match="unknown preset"):
        config.presets("tpu")


def test_json_round_trip():
    cfgs = config.preset("paper")
    back = config.from_dict(json.loads(json.dumps(config.to_dict(cfgs))))
    assert back == cfgs
    with pytest.raises(ValueError):
        config.from_dict({"vae": {"nope": 1}})


def test_validation():
    with pytest.raises(ValueError, match="multiple of 32"):
        DenoiserConfig(image_size=48)
    with pytest.raises(ValueError, match="4 conv_dims"):
        DenoiserConfig(conv_dims=(8, 16, 32))
    with pytest.raises(ValueError):
        VAEConfig(width=0)
    with pytest.raises(ValueError):
        SDEConfig(theta0=-1.0)
