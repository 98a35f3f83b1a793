"""The registry: names, codes, aliases and clear errors."""

from __future__ import annotations

import pytest

from readjax import tasks


def test_names_and_codes_agree():
    codes = tasks.codes()
    assert set(codes) == set(tasks.names())
    for name, code in codes.items():
        assert tasks.canonical_name(code) == name
        assert tasks.canonical_name(code.lower()) == name
        assert tasks.canonical_name(name.upper()) == name
        assert tasks.task_class(name).code == code and tasks.task_class(name).name == name


def test_order_is_the_papers():
    order = [tasks.AVG16.index(c) for c in tasks.codes().values()]
    assert order == sorted(order)


def test_unknown_task_lists_the_known_ones():
    with pytest.raises(tasks.UnknownTaskError, match="reach_target"):
        tasks.canonical_name("reach_targets")


def test_make_is_cached_across_aliases():
    assert tasks.make("RT") is tasks.make("reach_target")
