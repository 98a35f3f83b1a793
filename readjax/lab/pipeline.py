"""A resumable grid of (task x method) work: generate -> verify -> train -> evaluate -> results/.

Each step is one existing command (``experiments.generate``, ``verify``, ``train``, ``evaluate``)
run as a subprocess, and each has a test for "done" on disk, so running the grid again skips what
is finished and a kill loses at most the step in progress (the commands resume themselves too).
A test split must replay its ground truth at 100 % before anything is trained on its task: a
number from a split that does not is not a result. The replay is recorded per version of the split
(``results/<task>/verify/test_<fingerprint>.json``, see ``readjax.verification``). Finished
evaluations are copied to ``results/<task>/<run>/eval/<name>.json``, which ``experiments.report
--runs results/`` reads, and an evaluation counts as done when ``results/`` holds it on a split whose
replay is on record: so a fresh machine with only the committed ``results/`` skips every finished
evaluation, and generates, verifies and trains only what an unfinished one needs.
READ's first few test episodes at its largest N are evaluated once more, apart, to render them: the
overlay of retrieved / planned / ground-truth motions and a rollout video go to
``results/<task>/<run>/media/`` (the report shows them); their outcomes must equal the 100-episode
evaluation's on the same seeds, since an episode's result may not depend on its batch.
Beyond the main table: ``protocols`` adds READ's evaluations for the paper's other tables (oracle
and poor retrieval, perturbed images: ``PROTOCOL_EVALUATIONS``), and ``variants`` trains a method with its own
config overrides in a run folder of its own (READ-O's two samplers, READ with the kinematics-aware
autoencoder), each a row of its own.
This module plans the steps (``plan_steps``); ``readjax.scheduler`` runs them, in order or J at once.
"""

from __future__ import annotations

import json
import shutil
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from readjax import methods, result_record, stage_folder, tasks, verification
from readjax.scheduler import TIMING_FILE, PipelineError, Step, train_command


@dataclass(frozen=True)
class PipelineConfig:
    tasks: tuple[str, ...]
    methods: tuple[str, ...] = ("read", "deterministic")
    preset: str = "cpu"
    data: str = "data"
    runs: str = "runs"
    results: str = "results"
    train_episodes: int = 1000
    test_episodes: int = 100
    image_size: int = 64
    gen_batch: int = 32
    read_N: tuple[int, ...] = (0, 100)
    overrides: tuple[str, ...] = ()  # --set for every training
    shard: tuple[int, int] = (0, 1)  # (index, count): this process runs tasks[index::count]
    run_names: tuple[tuple[str, str], ...] = ()  # (method, run name); a method not named: its own name
    media_episodes: int = 8  # READ's first k test episodes (at most all) rendered: overlay + video; 0: none
    diagnose_below: float = 80.0  # READ below this % at its largest N: also evaluated from the oracle's start
    # (label, method, overrides): a method trained with its own config overrides, in its own run
    # folder (default: the label), e.g. ("read_o_em", "read_o", ("read_o.sampler=em",)); its label
    # goes in ``methods`` like a method's name
    variants: tuple[tuple[str, str, tuple[str, ...]], ...] = ()
    protocols: tuple[str, ...] = ()  # READ's evaluations beyond the main table: keys of PROTOCOL_EVALUATIONS
    noise: float = 0.05  # Table 9's perturbations (the paper does not state its levels): RGB noise std
    brightness: float = 0.7  # and the brightness factor

    def validate(self) -> "PipelineConfig":
        names = tuple(tasks.canonical_name(t) for t in self.tasks)
        i, n = self.shard
        if not (n >= 1 and 0 <= i < n):
            raise ValueError(f"--shard must be i/n with 0 <= i < n, got {i}/{n}")
        if self.media_episodes < 0:
            raise ValueError(f"--media-episodes must be >= 0, got {self.media_episodes}")
        if not 0.0 <= self.diagnose_below <= 100.0:
            raise ValueError(f"--diagnose-below is a percentage in [0, 100], got {self.diagnose_below}")
        variant_labels = [label for label, _, _ in self.variants]
        for label, method, sets in self.variants:
            if label in methods.names() or variant_labels.count(label) > 1:
                raise ValueError(f"--variant {label}: the label must differ from every method's name and "
                                 f"every other variant's")
            if not label or "/" in label:
                raise ValueError(f"--variant {label!r}: a label is one folder name")
            methods.module(method)
            bad = [kv for kv in sets if "=" not in kv]
            if bad:
                raise ValueError(f"--variant {label}: overrides look like KEY=VALUE, got {bad}")
        for m in self.methods:
            if m not in variant_labels:
                methods.module(m)
        from readjax import config
        for m in self.methods:  # a bad override fails here, not hours into the grid
            try:
                config.override(config.presets(self.preset), self.overrides_of(m))
            except ValueError as e:
                raise ValueError(f"{m}: {e}") from None
        for m, name in self.run_names:
            if m not in self.methods:
                raise ValueError(f"--run-name names method {m!r}, which is not among --methods {' '.join(self.methods)}")
            if not name or "/" in name:
                raise ValueError(f"--run-name {m}={name!r}: a run name is one folder name")
        unknown = [x for x in self.protocols if x not in PROTOCOL_EVALUATIONS]
        if unknown:
            raise ValueError(f"--protocols: unknown {unknown}; choose among {' '.join(PROTOCOL_EVALUATIONS)}")
        if "poor" in self.protocols and self.train_episodes < POOR_RANK:
            raise ValueError(f"the poor protocol retrieves the {POOR_RANK}th nearest training demonstration: "
                             f"--train-episodes must be at least {POOR_RANK}, got {self.train_episodes}")
        if self.protocols and "read" not in self.methods:
            raise ValueError("--protocols evaluate READ's run: add read to --methods")
        if self.noise < 0 or self.brightness <= 0:
            raise ValueError(f"--noise must be >= 0 and --brightness > 0, got {self.noise} and {self.brightness}")
        if "perturbed" in self.protocols and (self.noise == 0 or self.brightness == 1.0):
            raise ValueError("the perturbed protocol needs --noise > 0 and --brightness != 1 (else it repeats "
                             "the clean evaluation)")
        return PipelineConfig(**{**self.__dict__, "tasks": names})

    def run_name(self, label: str) -> str:
        """The run folder of a method or variant on each task (``--run-name``; default its label)."""
        return dict(self.run_names).get(label, label)

    def method_of(self, label: str) -> str:
        """The method a label of ``methods`` trains: a variant's, or the label itself."""
        return next((m for lab, m, _ in self.variants if lab == label), label)

    def overrides_of(self, label: str) -> tuple[str, ...]:
        """Config overrides of a label's training: the grid's (``overrides``), then the variant's."""
        return self.overrides + next((sets for lab, _, sets in self.variants if lab == label), ())


def _summary_kept(split_dir: Path) -> int:
    f = split_dir / "summary.json"
    return json.loads(f.read_text()).get("episodes_kept", 0) if f.exists() else 0


@dataclass(frozen=True)
class EvalRequest:
    """One evaluation of a run on the test split: N refinement steps (None: the method's default,
    for a method evaluated once), from SPE's top-1 or the oracle's ``rank``-th nearest training
    demonstration, on clean images or with Gaussian ``noise`` / a ``brightness`` factor on the RGB.
    ``experiments.evaluate`` names the result from these options."""
    n: int | None = None
    rank: int | None = None  # None: SPE top-1
    noise: float = 0.0
    brightness: float = 1.0

    def argv(self) -> list[str]:
        out = [] if self.n is None else ["--N", str(self.n)]
        if self.rank is not None:
            out += ["--retrieval", "cheat", "--rank", str(self.rank)]
        if self.noise:
            out += ["--noise", f"{self.noise:g}"]
        if self.brightness != 1.0:
            out += ["--brightness", f"{self.brightness:g}"]
        return out

    def label(self, method: str) -> str:
        """The step's label (also the key of its recorded wall clock, which prices the ETA of the same
        step on other tasks: the labels of earlier grids are kept)."""
        where = ("" if self.rank is None else " from the oracle's start" if self.rank == 1
                 else f" from the oracle's {_ordinal(self.rank)} neighbour")
        images = "".join([f" on noisy images (std {self.noise:g})" if self.noise else "",
                          f" at brightness x{self.brightness:g}" if self.brightness != 1.0 else ""])
        steps = "" if self.n is None else f" --N {self.n}"
        return f"evaluate {method}{where}{images}{steps}"

    def matches(self, r: dict, method: str) -> bool:
        return result_record.is_default_eval(r, method, self.n, self.rank, self.noise, self.brightness)


def _ordinal(k: int) -> str:
    return f"{k}{'th' if 10 <= k % 100 <= 20 else {1: 'st', 2: 'nd', 3: 'rd'}.get(k % 10, 'th')}"


# The paper's protocols beyond the main table, each a set of READ evaluations (``--protocols``);
# ``top`` is the largest --read-N.
PROTOCOL_EVALUATIONS = {
    "oracle": "Tables 4 and 5: from the oracle's i-th nearest demonstration, i = 1, 3, 10, at N = 0 and top "
              "(READ-O and READ-L runs too, at their default N: Table 4's rows)",
    "poor": "Table 8: from the oracle's 500th neighbour (a poor retrieval) at N = 0, 1 and top",
    "perturbed": "Table 9: SPE top-1 at N = top on test images with Gaussian noise (--noise) and with a "
                 "brightness factor (--brightness)",
}
ORACLE_RANKS = (1, 3, 10)
POOR_RANK = 500
# Table 4 also starts the two ablations from the oracle's i-th neighbour (refined at their default N):
# with the oracle protocol, their runs (and variants) are evaluated so too
ORACLE_ABLATIONS = ("read_o", "read_l")


def eval_requests(method: str, read_n) -> list[EvalRequest]:
    """The main-table evaluations of a method: READ at each N, the others once with their defaults."""
    if method == "read":
        return [EvalRequest(n) for n in read_n]
    return [EvalRequest()]


def protocol_requests(cfg: "PipelineConfig") -> list[EvalRequest]:
    """READ's evaluations for ``cfg.protocols`` (see ``PROTOCOL_EVALUATIONS``), in that order, without repeats."""
    top, out = max(cfg.read_N), []
    for name in cfg.protocols:
        if name == "oracle":
            out += [EvalRequest(n, rank) for rank in ORACLE_RANKS for n in sorted({0, top})]
        elif name == "poor":
            out += [EvalRequest(n, POOR_RANK) for n in sorted({0, 1, top})]
        elif name == "perturbed":
            out += [EvalRequest(top, noise=cfg.noise), EvalRequest(top, brightness=cfg.brightness)]
    return list(dict.fromkeys(out))


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


def label_configs(cfg: PipelineConfig, label: str) -> dict:
    """The configs (every section, train included) a ``label`` run of this grid trains with."""
    from readjax import config
    return config.override(config.presets(cfg.preset), cfg.overrides_of(label))


def recipe(cfg: PipelineConfig, label: str) -> dict:
    """Every config section a ``label`` run of this grid is trained with (the preset and the
    overrides), as a result JSON records it."""
    from readjax import config
    configs = label_configs(cfg, label)
    sections = [k for k in configs if k != "train"]
    return json.loads(json.dumps(config.configs_to_dict(configs, sections)))


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


def check_recipes(cfg: PipelineConfig) -> None:
    """Refuse a grid whose run folders in ``results/`` hold evaluations of another recipe: the
    finished ones would be counted as this grid's, and a run retrained on another machine under the
    same name would mix two recipes in one row. Nothing is run or written."""
    results = Path(cfg.results)
    i, n = cfg.shard
    for task in cfg.tasks[i::n]:
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
    ``result_record.is_default_eval``) over ``episodes`` test episodes, on a test split whose
    ground-truth replay is on record at 100 %."""
    for f in sorted((results / task / run_name / "eval").glob("*.json")):
        try:
            r = json.loads(f.read_text())
        except json.JSONDecodeError:
            continue
        if (r.get("task") == task and r.get("episodes") == episodes
                and request.matches(r, method)
                and verification.evaluation_verified(results, r)):
            return r
    return None


def train_argv(cfg: PipelineConfig, task: str, label: str, python: str) -> list[str]:
    """The ``experiments.train`` command of a ``label`` run of this grid on ``task``."""
    return train_command(python, task=task, model=cfg.method_of(label), preset=cfg.preset, name=cfg.run_name(label),
                         data=cfg.data, out=cfg.runs, overrides=cfg.overrides_of(label))


def plan_steps(cfg: PipelineConfig, python: str = sys.executable) -> list[Step]:
    """The grid's steps in order, this shard's tasks only. A step that only feeds others (generate,
    verify, train) also counts as done once everything it feeds is: a task whose evaluations and
    media are all in ``results/`` needs no dataset, replay or checkpoint on this machine. Refused
    (``check_recipes``) where ``results/`` holds a run of the same name trained another way."""
    check_recipes(cfg)
    data, runs, results = Path(cfg.data), Path(cfg.runs), Path(cfg.results)
    i, n = cfg.shard
    steps: list[Step] = []
    for task in cfg.tasks[i::n]:
        prepare: list[Step] = []  # the task's datasets and their replay
        for split, count in (("test", cfg.test_episodes), ("train", cfg.train_episodes)):
            d = data / task / split
            prepare.append(Step("generate", task, f"generate {split} {count}", [
                python, "-m", "experiments.generate", "--task", task, "--split", split, "--episodes", str(count),
                "--batch-size", str(cfg.gen_batch), "--image-size", str(cfg.image_size), "--out", str(data),
                "--quiet"], made=lambda d=d, c=count: _summary_kept(d) >= c))
            if split == "test":
                prepare.append(Step("verify", task, "verify test (ground truth replay = 100 %)", [
                    python, "-m", "experiments.verify", "--task", task, "--data", str(data), "--episodes", str(count),
                    "--results", str(results), "--min", "100"],
                    made=lambda d=d, c=count, task=task: verification.is_verified(
                        results, task, split_fingerprint(d, c), c)))
        prepare[1].needs.append(prepare[0])  # the replay reads the generated test split
        steps += prepare
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
                    if source in trains:  # never two trainings of one autoencoder at once (jobs > 1)
                        trains[source].needs.append(shared[source])
                        # listed just before the source's training, which now waits on it: the scheduler
                        # starts ready steps in list order, so placed at its first user's position it
                        # would hold READ back until every earlier baseline had started
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
            uses = [evaluate_step(cfg, task, run, method, request, python, shown=label)
                    for request in eval_requests(method, cfg.read_N)]
            if "oracle" in cfg.protocols and method in ORACLE_ABLATIONS:
                uses += [evaluate_step(cfg, task, run, method, EvalRequest(None, rank), python, shown=label)
                         for rank in ORACLE_RANKS]
            if label == "read":  # READ itself, not a variant: media, diagnosis and the paper's protocols
                top = uses[list(cfg.read_N).index(max(cfg.read_N))]  # what media and diagnosis compare with
                if cfg.media_episodes and max(cfg.read_N) > 0:
                    uses.append(media_step(cfg, task, run, python))
                    uses[-1].needs.append(top)
                protocol = protocol_requests(cfg)
                if cfg.diagnose_below > 0:
                    for n, step in zip(cfg.read_N, oracle_steps(cfg, task, run, python)):
                        if EvalRequest(n, 1) not in protocol:  # the oracle protocol runs it anyway
                            step.needs.append(top)
                            uses.append(step)
                uses += [evaluate_step(cfg, task, run, method, request, python) for request in protocol]
            train.users = uses
            steps += [train] + uses
            outputs += uses
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
                  label_suffix: str = "", wanted: Callable[[], bool] = lambda: True, shown: str | None = None) -> Step:
    """Evaluate ``run`` (a ``method`` run, labelled ``shown``: a variant's label) as ``request`` asks on
    the task's first ``cfg.test_episodes`` test episodes; done when ``results/`` holds that evaluation
    on a verified split (copied there after it runs)."""
    results = Path(cfg.results)
    argv = [python, "-m", "experiments.evaluate", "--run", str(run), "--data", cfg.data,
            "--episodes", str(cfg.test_episodes), "--videos", "0", "--quiet"] + request.argv()
    return Step("evaluate", task, request.label(shown or method) + label_suffix, argv,
                made=lambda: finished_evaluation(results, task, run.name, method, request,
                                                 cfg.test_episodes) is not None,
                after=lambda: copy_results(run, results), wanted=wanted)


def oracle_steps(cfg: PipelineConfig, task: str, run: Path, python: str) -> list[Step]:
    """Where READ at its largest N scores below ``cfg.diagnose_below`` %, READ again at each N from
    the oracle's start (the test episode's own demonstration, Table 4's i = 1): success there and
    not from SPE's start says retrieval limits the task; failure from the right start too says the
    refinement or the execution does. Skipped (``wanted`` false) when READ scores at least that."""
    results, top = Path(cfg.results), max(cfg.read_N)

    def weak() -> bool:
        r = finished_evaluation(results, task, run.name, "read", EvalRequest(top), cfg.test_episodes)
        return r is None or 100.0 * r["success_rate"] < cfg.diagnose_below  # not evaluated yet: assume so

    return [evaluate_step(cfg, task, run, "read", EvalRequest(n, 1), python,
                          label_suffix=f" (READ below {cfg.diagnose_below:g} %)", wanted=weak) for n in cfg.read_N]


MEDIA_VIDEOS = 4  # rollouts side by side in a task's video


def media_step(cfg: PipelineConfig, task: str, run: Path, python: str) -> Step:
    """Render READ's first ``media_episodes`` test episodes at its largest N: an evaluation of those
    episodes alone, written to RUN/media/ (outside RUN/eval/, so no table counts it), then copied
    to results/<task>/<run>/media/ (the pictures and the rendered evaluation's JSON) with its
    outcomes checked against the full evaluation's."""
    n = max(cfg.read_N)
    k = min(cfg.media_episodes, cfg.test_episodes)
    media, dest = run / "media", Path(cfg.results) / task / run.name / "media"
    argv = [python, "-m", "experiments.evaluate", "--run", str(run), "--data", cfg.data, "--episodes", str(k),
            "--batch-size", str(k), "--videos", str(min(MEDIA_VIDEOS, k)), "--N", str(n), "--out", str(media),
            "--quiet"]

    def publish():
        check_media(media, run / "eval")
        dest.mkdir(parents=True, exist_ok=True)
        for f in sorted(media.glob("*_overlay.png")) + sorted(media.glob("*_rollouts.mp4")) + sorted(media.glob("*.json")):
            shutil.copyfile(f, dest / f.name)  # the JSON: which episodes the pictures show, and their outcomes

    return Step("media", task, f"render READ N={n} ({k} episodes: overlay + video)", argv,
                made=lambda: any(dest.glob("*_rollouts.mp4")), after=publish)


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


def copy_results(run: Path, results: Path) -> None:
    """Mirror a run's evaluation JSONs into results/<task>/<run>/eval/ (small, committed), and its
    training records (:func:`copy_training_records`)."""
    for f in sorted((run / "eval").glob("*.json")):
        dest = results / run.parent.name / run.name / "eval" / f.name
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
