"""A resumable grid of (task x method) work: generate -> verify -> train -> evaluate -> results/.

Each step is one existing command (``experiments.generate``, ``verify``, ``train``, ``evaluate``)
run as a subprocess, and each has a test for "done" on disk, so running the grid again skips what
is finished and a kill loses at most the step in progress (the commands resume themselves too).
A test split must replay its ground truth at 100 % before anything is trained on its task: a
number from a split that does not is not a result. The replay is recorded per version of the split
(``results/<task>/verify/test_<fingerprint>.json``, see ``readjax.lab.verification``). Finished
evaluations are copied to ``results/<task>/<run>/eval/<name>.json``, which ``experiments.report
--runs results/`` reads, and an evaluation counts as done when ``results/`` holds it on a split whose
replay is on record: so a fresh machine with only the committed ``results/`` skips every finished
evaluation, and generates, verifies and trains only what an unfinished one needs.
READ's first few test episodes at its largest N are evaluated once more, apart, to render them: the
overlay of retrieved / planned / ground-truth motions and a rollout video go to
``results/<task>/<run>/media/`` (the report shows them); their outcomes must equal the 100-episode
evaluation's on the same seeds, since an episode's result may not depend on its batch.
Beyond the main table: ``protocols`` adds READ's evaluations for the paper's other tables (oracle
and poor retrieval, perturbed images: ``pipeline_config.PROTOCOL_EVALUATIONS``), and ``variants`` trains a method with its own
config overrides in a run folder of its own (READ-O's two samplers, READ with the kinematics-aware
autoencoder), each a row of its own.
With ``val_episodes`` > 0 each READ run chooses its refinement setting on a validation split (generated
and replayed like the test split) before its test evaluations use it (``readjax.lab.pipeline_val``).
This module plans the steps (``plan_steps``); ``readjax.lab.ray_grid`` runs them on Ray, each step a task on
whichever node has what it asks, after the steps it needs. What the grid is asked (its config, the
evaluations of each run, the recipe of each label) is ``readjax.lab.pipeline_config``; its records in
``results/`` (what is finished there, the copies into it) are ``readjax.lab.pipeline_results``.
"""

from __future__ import annotations

import json
import shutil
import sys
import time
from pathlib import Path
from typing import Callable

from readjax import methods, stage_folder
from readjax.lab import verification
from readjax.lab.pipeline_config import (ORACLE_ABLATIONS, ORACLE_RANKS, EvalRequest, PipelineConfig,
                                         eval_requests, label_configs, protocol_requests)
from readjax.lab.pipeline_results import (check_media, check_recipes, copy_results, copy_training_records,
                                          finished_evaluation)
from readjax.lab.pipeline_val import ValChoice, plan_choice
from readjax.lab.steps import Step, train_command
from readjax.lab.timing import TIMING_FILE


def _summary_kept(split_dir: Path) -> int:
    f = split_dir / "summary.json"
    return json.loads(f.read_text()).get("episodes_kept", 0) if f.exists() else 0


_FINGERPRINTS: dict[tuple, str] = {}  # (split, episodes, summary mtime) -> content hash


def split_fingerprint(split_dir: Path, episodes: int) -> str | None:
    """The content hash of the first ``episodes`` of the split in ``split_dir`` on this machine (what
    an evaluation of them records as ``test_fingerprint``); None while the split is not complete."""
    summary = split_dir / "summary.json"
    if _summary_kept(split_dir) < episodes:
        return None
    key = (str(split_dir.resolve()), episodes, summary.stat().st_mtime_ns)
    if key not in _FINGERPRINTS:
        from readjax.data import store
        _FINGERPRINTS[key] = store.load_dataset(split_dir, limit=episodes).fingerprint
    return _FINGERPRINTS[key]


def autoencoder_source(cfg: PipelineConfig, label: str) -> str | None:
    """The first earlier label of the grid whose run ``label``'s run starts its autoencoder from
    (``experiments.train --vae-from``): one with an autoencoder stage of the same stage config (a
    READ variant that changes only the denoiser, the SDE or K shares READ's). None: it trains its own."""
    from readjax import config, methods
    from readjax.methods import read as read_lib

    def stage_config(lab: str):
        if "vae" not in methods.stages(cfg.method_of(lab)):
            return None
        return read_lib.vae_stage_config(json.loads(json.dumps(config.configs_to_dict(label_configs(cfg, lab)))))

    mine = stage_config(label)
    if mine is None:
        return None
    return next((other for other in cfg.methods[:cfg.methods.index(label)] if stage_config(other) == mine), None)


def train_argv(cfg: PipelineConfig, task: str, label: str, python: str) -> list[str]:
    """The ``experiments.train`` command of a ``label`` run of this grid on ``task``."""
    return train_command(python, task=task, model=cfg.method_of(label), preset=cfg.preset, name=cfg.run_name(label),
                         data=cfg.data, out=cfg.runs, overrides=cfg.overrides_of(label))


def split_steps(cfg: PipelineConfig, task: str, split: str, count: int, python: str) -> list[Step]:
    """Generate ``task``'s ``split`` (``count`` episodes); a test or val split then replays its ground
    truth, which must succeed 100 % (recorded per version of the split under ``results/``)."""
    data, results = Path(cfg.data), Path(cfg.results)
    d = data / task / split
    gen = Step("generate", task, f"generate {split} {count}", [
        python, "-m", "experiments.generate", "--task", task, "--split", split, "--episodes", str(count),
        "--batch-size", str(cfg.gen_batch), "--image-size", str(cfg.image_size), "--out", str(data), "--quiet"],
        made=lambda: _summary_kept(d) >= count)
    if split == "train":
        return [gen]
    return [gen, Step("verify", task, f"verify {split} (ground truth replay = 100 %)", [
        python, "-m", "experiments.verify", "--task", task, "--data", str(data), "--split", split,
        "--episodes", str(count), "--results", str(results), "--min", "100"],
        made=lambda: verification.is_verified(results, task, split_fingerprint(d, count), count, split=split),
        needs=[gen])]  # the replay reads the generated split


def plan_steps(cfg: PipelineConfig, python: str = sys.executable) -> list[Step]:
    """The grid's steps in order, each after the steps it ``needs``. A step that only feeds others (generate,
    verify, train, a val evaluation, a choice) also counts as done once everything it feeds is: a task whose
    evaluations and media are all in ``results/`` needs no dataset, replay or checkpoint on this machine.
    Refused (``check_recipes``) where ``results/`` holds a run of the same name trained another way."""
    check_recipes(cfg)
    runs, results = Path(cfg.runs), Path(cfg.results)
    steps: list[Step] = []
    validating = any(cfg.chooses(label) for label in cfg.methods)
    for task in cfg.tasks:
        # the task's datasets and their replay; the val split's, where a READ run chooses on it
        prepare = (split_steps(cfg, task, "test", cfg.test_episodes, python)
                   + split_steps(cfg, task, "train", cfg.train_episodes, python))
        val_prepare = split_steps(cfg, task, "val", cfg.val_episodes, python) if validating else []
        steps += prepare + val_prepare
        outputs: list[Step] = []  # the task's evaluations and media: what the rest is for
        shared: dict[str, Step] = {}  # label -> the step training that label's autoencoder stage alone
        trains: dict[str, Step] = {}  # label -> its training step
        for label in cfg.methods:
            method = cfg.method_of(label)
            run = runs / task / cfg.run_name(label)
            marker = run / "pipeline_trained.json"
            argv = train_argv(cfg, task, label, python)
            source = autoencoder_source(cfg, label)
            if source is not None:  # this run starts from the source run's autoencoder, trained once
                source_run = runs / task / cfg.run_name(source)
                argv += ["--vae-from", str(source_run)]
                if source not in shared:
                    shared[source] = Step("train", task, f"train {source} (autoencoder only)",
                                          train_argv(cfg, task, source, python) + ["--stage", "vae"],
                                          made=lambda r=source_run: stage_folder.is_finished(r / "vae"),
                                          needs=list(prepare), resumes=True,
                                          seconds_left=lambda r=source_run: stage_folder.seconds_left(r, ("vae",)))
                    if source in trains:  # never two trainings of one autoencoder at once
                        trains[source].needs.append(shared[source])
                        # listed just before the source's training, which now waits on it: Ray is handed
                        # the steps in list order, so placed at its first user's position it would hold
                        # READ back until every earlier baseline had been handed over
                        at = next(i for i, s in enumerate(steps) if s is trains[source])
                        steps.insert(at, shared[source])
                    else:
                        steps.append(shared[source])
            train = Step("train", task, f"train {label}", argv, made=marker.exists,
                         after=lambda marker=marker, run=run: _trained(marker, run, results),
                         progress=lambda run=run: stage_folder.progress(run), resumes=True,
                         seconds_left=lambda run=run, st=methods.stages(method): stage_folder.seconds_left(run, st),
                         needs=list(prepare))  # nothing trains before its task's replay holds
            trains[label] = train
            if label in shared:
                train.needs.append(shared[label])
            if source is not None:
                shared[source].users.append(train)
            val = plan_choice(cfg, task, label, run, python) if cfg.chooses(label) else None
            chosen = [] if val is None else val.evaluations  # what the choice is made from, on the val split
            uses = [evaluate_step(cfg, task, run, method, request, python, shown=label, choice=val)
                    for request in eval_requests(method, cfg.read_N)]
            if "oracle" in cfg.protocols and method in ORACLE_ABLATIONS:
                uses += [evaluate_step(cfg, task, run, method, EvalRequest(None, rank), python, shown=label)
                         for rank in ORACLE_RANKS]
            if label == "read":  # READ itself, not a variant: media, diagnosis and the paper's protocols
                top = uses[list(cfg.read_N).index(max(cfg.read_N))]  # what media and diagnosis compare with
                if cfg.media_episodes and max(cfg.read_N) > 0:
                    uses.append(media_step(cfg, task, run, python, choice=val))
                    uses[-1].needs.append(top)
                protocol = protocol_requests(cfg)
                if cfg.diagnose_below > 0:
                    for n, step in zip(cfg.read_N, oracle_steps(cfg, task, run, python, choice=val)):
                        if EvalRequest(n, 1) not in protocol:  # the oracle protocol runs it anyway
                            step.needs.append(top)
                            uses.append(step)
                uses += [evaluate_step(cfg, task, run, method, request, python, choice=val) for request in protocol]
            elif label in cfg.protocol_runs:  # a READ variant under the same protocols, shown by its label
                uses += [evaluate_step(cfg, task, run, method, request, python, shown=label, choice=val)
                         for request in protocol_requests(cfg)]
            train.users = chosen + uses
            steps += [train] + chosen + ([val.step] if val else []) + uses
            outputs += chosen + uses
            for step in val_prepare:
                step.users += chosen
        for step in prepare:
            step.users = outputs
    for s in steps:
        s.timing = results / s.task / TIMING_FILE
        for u in s.users:  # what uses a step's output starts after it
            u.needs.append(s)
    return steps


def _trained(marker: Path, run: Path, results: Path) -> None:
    """After a training step: its marker, and its stages' records in results/."""
    marker.write_text(json.dumps({"finished": time.time()}))
    copy_training_records(run, results)


def evaluate_step(cfg: PipelineConfig, task: str, run: Path, method: str, request: EvalRequest, python: str,
                  label_suffix: str = "", wanted: Callable[[], bool] = lambda: True, shown: str | None = None,
                  choice: ValChoice | None = None) -> Step:
    """Evaluate ``run`` (a ``method`` run, labelled ``shown``: a variant's label) as ``request`` asks on
    the task's first ``cfg.test_episodes`` test episodes; done when ``results/`` holds that evaluation
    on a verified split (copied there after it runs). ``choice``: the run's refinement chosen on the
    validation split, which an evaluation that refines takes (and waits for)."""
    results = Path(cfg.results)
    if choice is not None:
        request = choice.request(request)
    chooses = request.choice is not None
    argv = [python, "-m", "experiments.evaluate", "--run", str(run), "--data", cfg.data,
            "--episodes", str(cfg.test_episodes), "--videos", "0", "--quiet"] + request.argv()
    step = Step("evaluate", task, request.label(shown or method) + label_suffix, argv,
                made=lambda: (not chooses or choice.step.made()) and finished_evaluation(
                    results, task, run.name, method, request, cfg.test_episodes) is not None,
                after=lambda: copy_results(run, results), wanted=wanted)
    if chooses:
        choice.step.users.append(step)
    return step


def oracle_steps(cfg: PipelineConfig, task: str, run: Path, python: str,
                 choice: ValChoice | None = None) -> list[Step]:
    """Where READ at its largest N scores below ``cfg.diagnose_below`` %, READ again at each N from
    the oracle's start (the test episode's own demonstration, Table 4's i = 1): success there and
    not from SPE's start says retrieval limits the task; failure from the right start too says the
    refinement or the execution does. Skipped (``wanted`` false) when READ scores at least that."""
    results, top = Path(cfg.results), max(cfg.read_N)
    read_top = EvalRequest(top) if choice is None else choice.request(EvalRequest(top))

    def weak() -> bool:
        r = finished_evaluation(results, task, run.name, "read", read_top, cfg.test_episodes)
        return r is None or 100.0 * r["success_rate"] < cfg.diagnose_below  # not evaluated yet: assume so

    return [evaluate_step(cfg, task, run, "read", EvalRequest(n, 1), python, choice=choice,
                          label_suffix=f" (READ below {cfg.diagnose_below:g} %)", wanted=weak) for n in cfg.read_N]


MEDIA_VIDEOS = 4  # rollouts side by side in a task's video


def media_step(cfg: PipelineConfig, task: str, run: Path, python: str, choice: ValChoice | None = None) -> Step:
    """Render READ's first ``media_episodes`` test episodes at its largest N (refined as ``choice``
    chose, where the run chooses): an evaluation of those episodes alone, written to RUN/media/
    (outside RUN/eval/, so no table counts it), then copied to results/<task>/<run>/media/ (the
    pictures and the rendered evaluation's JSON) with its outcomes checked against the full
    evaluation's."""
    n = max(cfg.read_N)
    k = min(cfg.media_episodes, cfg.test_episodes)
    media, dest = run / "media", Path(cfg.results) / task / run.name / "media"
    argv = [python, "-m", "experiments.evaluate", "--run", str(run), "--data", cfg.data, "--episodes", str(k),
            "--batch-size", str(k), "--videos", str(min(MEDIA_VIDEOS, k)), "--N", str(n), "--out", str(media),
            "--quiet"] + ([] if choice is None else ["--choice", str(choice.path)])

    def publish():
        check_media(media, run / "eval")
        dest.mkdir(parents=True, exist_ok=True)
        for f in sorted(media.glob("*_overlay.png")) + sorted(media.glob("*_rollouts.mp4")) + sorted(media.glob("*.json")):
            shutil.copyfile(f, dest / f.name)  # the JSON: which episodes the pictures show, and their outcomes

    step = Step("media", task, f"render READ N={n} ({k} episodes: overlay + video)", argv,
                made=lambda: any(dest.glob("*_rollouts.mp4")), after=publish)
    if choice is not None:  # its command reads the choice file
        choice.step.users.append(step)
    return step
