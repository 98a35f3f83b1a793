"""The grid's validation path for one READ run: its refinement setting chosen on the validation split
before any test evaluation uses it.

For a READ run that chooses (``PipelineConfig.chooses``), :func:`plan_choice` plans one evaluation of
the task's val split per setting of the grid's ``ChoiceGrid`` (``experiments.evaluate --split val`` at
the largest --read-N; its record in RUN/val/, copied to results/<task>/<run>/val/), then the choice
step (``experiments.choose``), which writes results/<task>/<run>/choice.json. The run's evaluations
that refine (N > 0) take that file (:meth:`ValChoice.request`: ``experiments.evaluate --choice``) and
wait for it. What counts as done follows the test evaluations' rule: a val evaluation when
results/ holds it on a val split whose replay is on record, the choice when results/ holds one over
the same settings, N and episodes on such a split (``readjax.lab.choice.finished_choice``). The val
split itself is generated and replayed like the test split (``readjax.lab.pipeline.split_steps``).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

from readjax.lab import choice
from readjax.lab.pipeline_config import EvalRequest, PipelineConfig, label_configs
from readjax.lab.pipeline_results import copy_results
from readjax.lab.steps import Step


@dataclass
class ValChoice:
    """One READ run's validation: its candidates' val evaluations, the choice step, the choice file."""
    evaluations: list[Step]
    step: Step
    path: Path

    def request(self, request: EvalRequest) -> EvalRequest:
        """``request`` refined with the chosen setting where it refines (N > 0; N = 0 executes the
        retrieval, which no setting changes)."""
        return request if request.n == 0 else dataclasses.replace(request, choice=str(self.path))


def settings_of(cfg: PipelineConfig, label: str):
    """The refinement settings the ``label`` run chooses among: the grid's, the run's own rounds and
    update filled in."""
    return cfg.choice_grid.settings(label_configs(cfg, label)["sde"])


def plan_choice(cfg: PipelineConfig, task: str, label: str, run: Path, python: str) -> ValChoice:
    """The val evaluations of the ``label`` run (folder ``run``) on ``task``, one per setting, and the
    step choosing among them."""
    results, top, episodes = Path(cfg.results), max(cfg.read_N), cfg.val_episodes
    settings = settings_of(cfg, label)
    evaluations = []
    for s in settings:
        argv = [python, "-m", "experiments.evaluate", "--run", str(run), "--data", cfg.data, "--split", "val",
                "--episodes", str(episodes), "--videos", "0", "--quiet", "--N", str(top)] + s.argv()
        evaluations.append(Step(
            "evaluate", task, f"evaluate {label} on val --N {top} ({s.text()})", argv,
            made=lambda s=s: bool(choice.val_records(results, task, run.name, s, top, episodes)),
            after=lambda: copy_results(run, results, folder=choice.VAL_FOLDER)))
    argv = [python, "-m", "experiments.choose", "--task", task, "--run-name", run.name, "--N", str(top),
            "--episodes", str(episodes), "--results", str(results)]
    argv += [a for s in settings for a in ("--setting", s.text())]
    step = Step("choose", task, f"choose {label}'s refinement on val ({len(settings)} settings)", argv,
                made=lambda: choice.finished_choice(results, task, run.name, settings, top,
                                                    episodes) is not None)
    for e in evaluations:
        e.users.append(step)
    return ValChoice(evaluations, step, choice.choice_path(results, task, run.name))
