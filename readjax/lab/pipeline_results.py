"""The grid's records in ``results/`` (small, committed): which evaluation there is finished on a
verified split (``finished_evaluation``), a refusal where a run folder there holds another recipe
(``check_recipes``), and copying a run's evaluations, rendered media and training records into it
(``copy_results``, ``check_media``, ``copy_training_records``).
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

from readjax import stage_folder
from readjax.lab import result_record, verification
from readjax.lab.pipeline_config import EvalRequest, PipelineConfig, recipe
from readjax.lab.steps import PipelineError


def check_recipes(cfg: PipelineConfig) -> None:
    """Refuse a grid whose run folders in ``results/`` hold evaluations of another recipe: the
    finished ones would be counted as this grid's, and a run retrained on another machine under the
    same name would mix two recipes in one row. Nothing is run or written."""
    results = Path(cfg.results)
    for task in cfg.tasks:
        for label in cfg.methods:
            run = cfg.run_name(label)
            wanted = None
            for f in sorted((results / task / run / "eval").glob("*.json")):
                try:
                    recorded = json.loads(f.read_text()).get("configs") or {}
                except json.JSONDecodeError:
                    continue
                wanted = wanted or recipe(cfg, label)
                diff = result_record.recipe_differences(recorded, wanted)
                if diff:
                    raise PipelineError(
                        f"{f} was trained with another recipe than this grid's {label} (differs in "
                        f"{', '.join(diff)}): name this grid's runs apart (--run-name {label}=NEW_NAME) or "
                        f"use the same --preset / --set / --variant overrides")


def finished_evaluation(results: Path, task: str, run_name: str, method: str, request: EvalRequest,
                        episodes: int) -> dict | None:
    """The evaluation a step asks for, if ``results/<task>/<run>/eval/`` holds it: ``method``'s
    evaluation ``request`` (its default one at that N, start and images:
    ``result_record.is_default_eval``; or refined as its choice file says) over ``episodes`` test
    episodes, on a test split whose ground-truth replay is on record at 100 %. A validation record
    never counts, wherever it lies."""
    for f in sorted((results / task / run_name / "eval").glob("*.json")):
        try:
            r = json.loads(f.read_text())
        except json.JSONDecodeError:
            continue
        if (r.get("task") == task and r.get("episodes") == episodes and r.get("split", "test") == "test"
                and request.matches(r, method)
                and verification.evaluation_verified(results, r)):
            return r
    return None


def check_media(media: Path, eval_dir: Path) -> None:
    """The rendered episodes' outcomes equal those of the evaluation of the same name on the same
    seeds: a video that shows other outcomes than the table would mislead."""
    for f in sorted(media.glob("*.json")):
        shown = json.loads(f.read_text())
        full_file = eval_dir / f.name
        if "seeds" not in shown or not full_file.exists():
            continue
        by_seed = result_record.by_seed(json.loads(full_file.read_text()))
        differ = [s for s, ok in zip(shown["seeds"], shown["success"]) if s in by_seed and by_seed[s] != ok]
        if differ:
            raise PipelineError(f"{f.name}: seeds {differ} succeed in one evaluation and fail in the other "
                                f"({media} against {eval_dir}): an episode's outcome depends on its batch")


def copy_results(run: Path, results: Path, folder: str = "eval") -> None:
    """Mirror a run's evaluation JSONs into results/<task>/<run>/eval/ (small, committed), and its
    training records (:func:`copy_training_records`); ``folder="val"``: its validation evaluations,
    RUN/val/ into results/<task>/<run>/val/."""
    for f in sorted((run / folder).glob("*.json")):
        dest = results / run.parent.name / run.name / folder / f.name
        dest.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(f, dest)
    copy_training_records(run, results)


# why and when a stage stopped; its loss curve with the stop marked
TRAINING_RECORDS = (stage_folder.STOP_FILE, stage_folder.LOSS_CURVE)


def copy_training_records(run: Path, results: Path) -> None:
    """Mirror each finished stage's ``stop.json`` and loss curve into
    results/<task>/<run>/training/<stage>/ (small, committed): a baseline row is claimed converged,
    and its curve is the evidence, which must outlive the machine the checkpoints are on."""
    for stop in sorted(run.glob(f"*/{stage_folder.STOP_FILE}")):
        dest = results / run.parent.name / run.name / "training" / stop.parent.name
        dest.mkdir(parents=True, exist_ok=True)
        for name in TRAINING_RECORDS:
            if (stop.parent / name).exists():
                shutil.copyfile(stop.parent / name, dest / name)
