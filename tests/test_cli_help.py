"""Every command's --help explains itself: a description, each option's help, and a default shown only
where there is one (never "(default: None)", never twice)."""

import importlib
import pkgutil

import pytest

import experiments

COMMANDS = sorted(m.name for m in pkgutil.iter_modules(experiments.__path__)
                  if not m.name.startswith("_") and hasattr(importlib.import_module(f"experiments.{m.name}"), "parser"))


def test_the_commands_are_found():
    assert {"train", "evaluate", "pipeline", "difficulty", "report"} <= set(COMMANDS)


@pytest.mark.parametrize("name", COMMANDS)
def test_help_has_a_description_and_no_empty_default(name):
    p = importlib.import_module(f"experiments.{name}").parser()
    text = p.format_help()
    assert p.description and p.description.strip(), f"{name}: no description"
    assert "(default: None)" not in text, f"{name}: an option shows '(default: None)'"
    for action in p._actions:
        if action.option_strings and action.help is not None:
            assert action.help.strip(), f"{name} {action.option_strings}: empty help"
            assert action.help.count("(default:") <= 1, f"{name} {action.option_strings}: two defaults"
