"""A training stage's folder read without JAX: its records, progress against the cap, and the pace
that prices what is left of a training under way."""

from __future__ import annotations

import json

import pytest

from readjax import stage_folder
from readjax.lab.steps import Step
from readjax.lab.timing import step_cost


def _stage(vae: int, steps: int) -> str:
    return json.dumps({"config": {"train": {"vae_steps": vae, "steps": steps}}})


def test_records_and_progress_of_a_run(tmp_path):
    """Each stage's last logged step and stop record; progress lists the finished stages first, then
    each other one's step against its cap; nothing logged yet reads as ""."""
    run = tmp_path / "read"
    (run / "vae").mkdir(parents=True)
    (run / "read").mkdir()
    (run / "vae" / "stage.json").write_text(_stage(3000, 5000))
    (run / "vae" / "metrics.jsonl").write_text('{"step": 3000}\n')
    (run / "vae" / "stop.json").write_text('{"reason": "step cap", "stopped_at": 3000}')
    (run / "read" / "stage.json").write_text(_stage(3000, 5000))
    assert stage_folder.progress(run) == "vae done, read 0/5000"
    (run / "read" / "metrics.jsonl").write_text('{"step": 25}\n{"step": 2250}\n')
    assert stage_folder.progress(run) == "vae done, read 2250/5000"
    assert stage_folder.stage_records(run) == {"read": {"steps": 2250, "stop": None},
                                               "vae": {"steps": 3000, "stop": {"reason": "step cap", "stopped_at": 3000}}}
    assert stage_folder.step_cap(run / "vae") == 3000 and stage_folder.step_cap(run / "read") == 5000
    assert stage_folder.is_finished(run / "vae") and not stage_folder.is_finished(run / "read")
    assert stage_folder.progress(tmp_path / "nothing yet") == "" and stage_folder.step_cap(tmp_path) is None


def test_the_loss_curve_marks_the_stop(tmp_path):
    """A PNG once a step is logged (none before), written beside the records."""
    d = tmp_path / "read"
    d.mkdir()
    assert stage_folder.plot_losses(d, "read") is None
    (d / "metrics.jsonl").write_text("".join(json.dumps({"step": k, "time_s": k, "loss": 1.0 / k, "val_loss": 1.1 / k})
                                             + "\n" for k in (1, 2, 3)))
    (d / "stop.json").write_text('{"reason": "converged", "stopped_at": 3}')
    out = stage_folder.plot_losses(d, "read")
    assert out == d / "loss.png" and out.stat().st_size > 1000


def test_a_training_under_way_is_priced_by_its_own_pace(tmp_path):
    """The steps left to the cap times the seconds per step of the current run's last logged steps (the
    clock restarts with a resumed run; a finished stage costs nothing); no pace yet: priced whole."""
    run = tmp_path / "read"
    for stage in ("vae", "read"):
        (run / stage).mkdir(parents=True)
        (run / stage / "stage.json").write_text(json.dumps({"config": {"train": {"vae_steps": 3000, "steps": 5000}}}))
    (run / "vae" / "stop.json").write_text('{"reason": "step cap"}')
    assert stage_folder.seconds_left(run, ("vae", "read")) is None  # read has not logged a step
    first_run = [{"step": 25 * k, "time_s": 10.0 * k} for k in range(1, 41)]  # 0.4 s per step until 1000
    second_run = [{"step": 1000 + 25 * k, "time_s": 30.0 + 5.0 * k} for k in range(1, 3)]  # resumed: 0.2 s per step
    (run / "read" / "metrics.jsonl").write_text("".join(json.dumps(r) + "\n" for r in first_run + second_run[:1]))
    assert stage_folder.seconds_left(run, ("vae", "read")) is None  # one row into the resumed run
    (run / "read" / "metrics.jsonl").write_text("".join(json.dumps(r) + "\n" for r in first_run + second_run))
    assert stage_folder.seconds_left(run, ("vae", "read")) == pytest.approx((5000 - 1050) * 0.2)
    step = Step("train", "reach_target", "train read", ["x"], made=lambda: False,
                seconds_left=lambda: stage_folder.seconds_left(run, ("vae", "read")))
    prior = {"label": {"train read": [2100.0]}, "kind": {"train": [2100.0]}}
    assert step_cost(step, {}, {}, prior) == pytest.approx(790.0)  # its own pace before the others'
    assert step_cost(Step("train", "reach_target", "train read", ["x"], made=lambda: False), {}, {}, prior) == 2100.0
    assert stage_folder.seconds_left(tmp_path / "nothing yet", ("vae", "read")) is None
