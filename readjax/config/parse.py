"""``key=value`` overrides (from a CLI) and the JSON form of configs (checkpoints, ``run.json``).

:func:`override` applies overrides to a preset-style dict: every model section of ``SECTIONS``
and, where the dict has one, the ``train`` section. :func:`to_dict` / :func:`from_dict`
round-trip model sections through JSON; :func:`configs_to_dict` / :func:`configs_from_dict` a
run's configs (train included).
"""

from __future__ import annotations

import dataclasses
import types
import typing
from typing import Any, Iterable, Mapping

from readjax.config.presets import METHOD_SECTIONS, SECTIONS
from readjax.config.sections import INFERENCE_ONLY, TrainConfig

# Table 7's one-letter names for the SDE hyperparameters.
ALIASES = {"L": "sde.lam", "T": "sde.theta1"}


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
        return _parse_bool(s, text, where)
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


def _parse_bool(s: str, text: str, where: str) -> bool:
    """``s`` (``text`` as it is compared) as a boolean."""
    if s.lower() in ("1", "true", "yes", "on"):
        return True
    if s.lower() in ("0", "false", "no", "off"):
        return False
    raise ValueError(f"{where}: expected a boolean, got {text!r}")


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
    (``denoiser.enc_depths=1,1,2,1``); ``none`` sets an optional field to None. When ``configs``
    hold a ``train`` section (:func:`presets`), ``train.field`` and a bare train field name that
    no model section has (``steps``, ``K``) set it. The configs' own validation runs on the result.
    """
    if "train" not in configs:
        return _override_sections(configs, items)
    train_fields = {f.name for f in dataclasses.fields(TrainConfig)}
    train_kw, rest = {}, []
    for item in items:
        if "=" not in item:
            raise ValueError(f"override {item!r} is not of the form key=value")
        key, value = item.split("=", 1)
        field = key[len("train."):] if key.startswith("train.") else key
        if key.startswith("train.") or (field in train_fields and field not in _model_fields()):
            if field not in train_fields:
                raise ValueError(f"TrainConfig has no field {field!r}")
            tp = type(getattr(TrainConfig(), field))
            train_kw[field] = _parse_train(value, tp, f"train.{field}")
        else:
            rest.append(item)
    out = _override_sections({k: v for k, v in configs.items() if k != "train"}, rest)
    out["train"] = dataclasses.replace(configs["train"], **train_kw)
    return out


def _override_sections(configs: Mapping[str, Any], items: Iterable[str]) -> dict[str, Any]:
    """:func:`override` for the model sections (``SECTIONS``)."""
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


def _model_fields() -> set[str]:
    return {f.name for cls in SECTIONS.values() for f in dataclasses.fields(cls)}


def _parse_train(text: str, tp, where: str):
    """Parse a train field's value (``int``, ``float`` or ``bool``). Unlike :func:`_parse` it keeps
    the text as given (``" true"`` is no boolean) and its errors name the bare type."""
    if tp is bool:
        return _parse_bool(text, text, where)
    try:
        return tp(text)
    except ValueError:
        raise ValueError(f"{where}: expected {tp.__name__}, got {text!r}") from None


def field_defaults(section: str) -> dict[str, Any]:
    """JSON-form defaults (tuples as lists) of a section's fields with a default (``train`` or any
    of ``SECTIONS``; empty for an unknown section). A field added since a run was recorded ran with
    its default: new fields default to the old behaviour."""
    cls = TrainConfig if section == "train" else SECTIONS.get(section)
    if cls is None:
        return {}
    return {f.name: list(f.default) if isinstance(f.default, tuple) else f.default
            for f in dataclasses.fields(cls) if f.default is not dataclasses.MISSING}


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


def configs_to_dict(configs: Mapping[str, Any], sections=None) -> dict:
    """JSON-ready configs of a run: ``sections`` (default: every section except the method-specific
    ``METHOD_SECTIONS``, i.e. READ's vae/denoiser/sde) plus train."""
    if sections is None:
        keep = [k for k in configs if k != "train" and k not in METHOD_SECTIONS]
    else:
        missing = [k for k in sections if k not in configs]
        if missing:
            raise ValueError(f"configs have no section(s) {missing}")
        keep = list(sections)
    d = to_dict({k: configs[k] for k in keep})
    d["train"] = dataclasses.asdict(configs["train"])
    return d


def configs_from_dict(d: Mapping[str, Any]) -> dict[str, Any]:
    """Inverse of :func:`configs_to_dict`."""
    out = from_dict({k: v for k, v in d.items() if k != "train"})
    out["train"] = TrainConfig(**d["train"])
    return out


def without_inference_only(config: dict) -> dict:
    """``config`` without the fields that change inference only (``config.INFERENCE_ONLY``): what a
    stage's identity is checked on."""
    out = dict(config)
    for section, names in INFERENCE_ONLY.items():
        if isinstance(out.get(section), dict):
            out[section] = {k: v for k, v in out[section].items() if k not in names}
    return out
