"""The method registry and the config sections of section 10's methods: every method has the same
shape (STAGES, train, a model class), the CLIs offer exactly the registered methods and presets,
READ's recorded configs are unchanged by the new sections, and the new fields are settable."""

import argparse
import importlib
import inspect
import json

import pytest

from readjax import config, diffusion
from readjax import methods
from readjax.methods import base, common

METHOD_NAMES = {"read", "read_o", "read_l", "deterministic", "vpsde", "vpsde_cg"}


def test_registry():
    assert set(methods.names()) == METHOD_NAMES
    for name in methods.names():
        mod = methods.module(name)
        cls = getattr(mod, methods.METHODS[name][1])
        assert issubclass(cls, common.RunModel)
        assert isinstance(cls.uses_retrieval, bool) and isinstance(cls.iterative, bool)
        assert cls.iterative == (name != "deterministic")  # only Deterministic ignores N
        # every method module, READ's included, names its stages and trains them all by default
        assert isinstance(mod.STAGES, tuple) and mod.STAGES == methods.stages(name), name
        assert callable(mod.train)
        assert inspect.signature(mod.train).parameters["stages"].default == mod.STAGES, name
    assert methods.stages("read") == ("vae", "read")
    assert not methods.module("vpsde").VPSDEModel.uses_retrieval
    assert methods.module("vpsde_cg").VPSDECGModel.uses_retrieval
    with pytest.raises(ValueError, match="unknown method"):
        methods.module("nope")


def test_every_method_has_the_common_shape():
    """Every registered method satisfies base.Method, its model class base.MethodModel's interface,
    with one generate signature (features, retrieved, key, n_steps) and no default N of its own."""
    for name in methods.names():
        mod = methods.module(name)
        assert isinstance(mod, base.Method), name
        cls = getattr(mod, methods.METHODS[name][1])
        for attr in ("uses_retrieval", "iterative", "encode", "generate"):
            assert hasattr(cls, attr), (name, attr)
        params = inspect.signature(cls.generate).parameters
        assert list(params) == ["self", "features", "retrieved", "key", "n_steps"], name
        assert params["n_steps"].default is inspect.Parameter.empty, name
        if cls.uses_retrieval:
            assert hasattr(cls, "database_tokens") and hasattr(cls, "spe_distances"), name


def test_check_n_steps():
    assert common.check_n_steps(3) == 3 and common.check_n_steps(0) == 0
    for bad in (-1, 1.5, True, "3", None):
        with pytest.raises(ValueError, match="N must be a non-negative int"):
            common.check_n_steps(bad, name="N")
    with pytest.raises(ValueError, match="samples from noise"):
        common.check_n_steps(0, allow_zero=False, method="vpsde")


def _option(parser: argparse.ArgumentParser, flag: str) -> argparse.Action:
    return next(a for a in parser._actions if flag in a.option_strings)


@pytest.mark.parametrize("cli, flag", [("train", "--model"), ("sweep", "--model"), ("pipeline", "--methods")])
def test_cli_methods_are_the_registry(cli, flag):
    parser = importlib.import_module(f"experiments.{cli}").parser()
    assert tuple(_option(parser, flag).choices) == methods.names()


def test_cli_presets_are_the_configs():
    for cli in ("train", "sweep", "pipeline"):
        parser = importlib.import_module(f"experiments.{cli}").parser()
        assert set(_option(parser, "--preset").choices) == set(config.preset_names()), cli
    bench = importlib.import_module("experiments.bench").parser()
    sub = next(a for a in bench._actions if isinstance(a, argparse._SubParsersAction))
    presets = _option(sub.choices["planner"], "--presets")
    assert set(presets.choices) == set(presets.default) == set(config.preset_names())


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
    with pytest.raises(ValueError, match="sampler must be one of"):
        config.override(config.presets("cpu"), ["vpsde.sampler=heun"])
    assert config.preset("cpu")["resnet"].input_size == config.preset("cpu")["denoiser"].image_size
    hash(tuple(config.preset("paper").values()))  # raises if a section is unhashable (jit static args)


def test_diffusion_package_exports_its_samplers():
    assert set(diffusion.__all__) == {"irsde", "refine", "taskspace", "vpsde"}
    for name in diffusion.__all__:
        assert getattr(diffusion, name) is not None, name
    assert callable(diffusion.refine) and callable(diffusion.vpsde.sample)
