"""The method registry and the config sections of section 10's methods: every method loads, READ's
recorded configs are unchanged by the new sections, and the new fields are settable."""

import dataclasses
import importlib
import json

import pytest

from readjax import config
from readjax import methods


def test_registry():
    assert set(methods.names()) >= {"read", "read_o", "read_l", "deterministic", "vpsde", "vpsde_cg"}
    for name in methods.names():
        mod = methods.module(name)
        cls = getattr(mod, methods.METHODS[name][1])
        assert isinstance(cls.uses_retrieval, bool) and isinstance(cls.iterative, bool) and hasattr(mod, "train")
        assert cls.iterative == (name != "deterministic")  # only Deterministic ignores N
        if hasattr(mod, "STAGES"):
            assert tuple(mod.STAGES) == methods.stages(name)
    assert not methods.module("vpsde").VPSDEModel.uses_retrieval
    assert methods.module("vpsde_cg").VPSDECGModel.uses_retrieval


def test_read_runs_record_only_reads_sections():
    for preset in ("cpu", "paper"):
        d = config.configs_to_dict(config.presets(preset))
        assert set(d) == {"vae", "denoiser", "sde", "train"}
    d = config.configs_to_dict(config.presets("cpu"), ("denoiser", "vpsde"))
    assert set(d) == {"denoiser", "vpsde", "train"}
    back = config.configs_from_dict(json.loads(json.dumps(d)))
    assert back["vpsde"] == config.presets("cpu")["vpsde"]
    with pytest.raises(ValueError, match="no section"):
        config.configs_to_dict({"train": config.TrainConfig()}, ("resnet",))


def test_new_fields_are_settable():
    c = config.override(config.presets("cpu"), ["beta_max=10", "vpsde.sampler=sde", "read_o.sampler=em", "proj_dim=32",
                                                "resnet.stage_blocks=1,1,1,1", "guidance=2", "steps=7"])
    assert c["vpsde"].beta_max == 10 and c["vpsde"].sampler == "sde" and c["vpsde"].guidance == 2.0
    assert c["read_o"].sampler == "em" and c["resnet"].proj_dim == 32 and c["resnet"].stage_blocks == (1, 1, 1, 1)
    assert c["train"].steps == 7
    # names that existed before keep working bare; the new shared name needs its section
    assert config.override(config.presets("cpu"), ["latent_dim=16", "drop_path=0"])["vae"].latent_dim == 16
    with pytest.raises(ValueError, match="ambiguous"):
        config.override(config.presets("cpu"), ["sampler=em"])
    with pytest.raises(ValueError):
        config.override(config.presets("cpu"), ["vpsde.sampler=heun"])
    assert config.preset("cpu")["resnet"].input_size == config.preset("cpu")["denoiser"].image_size
    hash(tuple(config.preset("paper").values()))
    assert dataclasses.replace(config.ReadOConfig(), sampler="em").sampler == "em"
    importlib.import_module("readjax.diffusion").vpsde  # noqa: B018
