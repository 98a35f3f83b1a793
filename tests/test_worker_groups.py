"""`make test` runs two pytest-xdist workers, handed whole groups (``tests/conftest.py``): the
grouping must keep each task's expert rollout (cached per process) and each module-scoped fixture
in one worker."""

from __future__ import annotations

from readjax import tasks
from tests.conftest import xdist_group_of

NAMES = set(tasks.names())


def test_a_tasks_own_file_and_its_smoke_and_purity_cases_share_a_group():
    for task in NAMES:
        own = xdist_group_of(f"tests/tasks/test_{task}.py::test_expert_succeeds", NAMES)
        table = xdist_group_of(f"tests/tasks/test_{task}.py::test_truth_table[open-False]", NAMES)
        smoke = xdist_group_of(f"tests/tasks/test_smoke.py::test_task_smoke[{task}]", NAMES)
        purity = xdist_group_of(f"tests/tasks/test_scene_purity.py::test_scene_is_independent_of_batching[{task}]",
                                NAMES)
        assert own == table == smoke == purity == f"task:{task}"


def test_other_tests_are_grouped_by_their_file():
    a = xdist_group_of("tests/test_pipeline.py::test_plan_and_execute", NAMES)
    b = xdist_group_of("tests/test_pipeline.py::test_a_plan_does_not_depend_on_its_batch[0-renoise]", NAMES)
    assert a == b == "tests/test_pipeline.py"
    assert xdist_group_of("tests/tasks/test_registry.py::test_names", NAMES) == "tests/tasks/test_registry.py"
    # a task's name as a parameter outside tests/tasks/ does not move a test out of its file's group
    assert xdist_group_of("tests/data/test_verify.py::test_x[reach_target]", NAMES) == "tests/data/test_verify.py"
