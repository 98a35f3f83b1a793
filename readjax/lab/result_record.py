"""Reading one evaluation result (``RUN/eval/<name>.json``): which of the paper's protocols it
belongs to, the settings it ran with (fields it predates at what they then were), its configs with
defaults filled in, its outcomes by seed, and whether it is the evaluation a pipeline step asks for.
The report, the main table and the pipeline all read results through these, so they agree."""

from __future__ import annotations

import dataclasses

from readjax.config import DEFAULT_N, field_defaults, without_inference_only
from readjax.evaluation import EvalConfig

PROTOCOLS = {  # protocol -> heading of its table
    "main": "Methods x tasks (SPE retrieval where the method retrieves, clean test images)",
    "oracle": "Oracle retrieval of the i-th nearest neighbour (Tables 4, 5 and 8: cheat<i>_N<N>)",
    "perturbed": "Perturbed test images (Table 9)",
}


def protocol(r: dict) -> str:
    """Which of the paper's experiment protocols an evaluation belongs to (see ``PROTOCOLS``)."""
    cfg = r.get("eval_config", {})
    if cfg.get("image_noise", 0.0) or cfg.get("brightness", 1.0) != 1.0:
        return "perturbed"
    if cfg.get("retrieval") == "cheat":
        return "oracle"
    return "main"


def with_defaults(configs: dict) -> dict:
    """Recorded configs with every field a run predates filled in at its default (new fields
    default to the old behaviour), so runs of one recipe recorded by different readjax versions
    compare equal."""
    out = {}
    for section, values in configs.items():
        if isinstance(values, dict):
            values = {**field_defaults(section), **values}
        out[section] = values
    return out


DATA_DERIVED = {"denoiser": ("motion_mean", "motion_std")}  # filled from the training set, not the recipe


def recipe_differences(recorded: dict, wanted: dict) -> list[str]:
    """The ``section.field`` names in which a result's recorded configs differ from ``wanted``, over
    the sections the result records; fields a run predates count at their defaults, and
    inference-only (``config.INFERENCE_ONLY``) and data-derived (``DATA_DERIVED``) fields are not the
    recipe."""
    recorded = without_inference_only(with_defaults(recorded))
    wanted = without_inference_only(wanted)
    out = []
    for section, values in recorded.items():
        if not isinstance(values, dict):
            continue
        skip = set(DATA_DERIVED.get(section, ()))
        want = wanted.get(section, {})
        out += [f"{section}.{k}" for k in sorted((set(values) | set(want)) - skip) if values.get(k) != want.get(k)]
    return out


# what an evaluation recorded before an EvalConfig field existed ran with: the field's default, and
# one refinement round (rounds arrived later; evaluations record the rounds they ran)
_EVAL_DEFAULTS = {**{f.name: f.default for f in dataclasses.fields(EvalConfig)}, "rounds": 1}


def eval_config_of(r: dict) -> dict:
    """The evaluation settings a result ran with, fields it predates at what they then were."""
    return {**_EVAL_DEFAULTS, **(r.get("eval_config") or {})}


def by_seed(r: dict) -> dict[int, bool]:
    """A result's outcomes keyed by test seed (how two evaluations of the same episodes pair up)."""
    return dict(zip(r.get("seeds", []), r.get("success", [])))


def _refinement(r: dict) -> tuple[str | None, int]:
    """(update, rounds) an evaluation refined with; an evaluation that predates ``refine_update``
    ran its run's ``sde.update`` (a method without READ's update records None)."""
    cfg = eval_config_of(r)
    return cfg.get("refine_update", _run_sde(r).get("update")), cfg["rounds"]


def _run_sde(r: dict) -> dict:
    return with_defaults(r.get("configs") or {"sde": {}}).get("sde", {})


def _clean_spe_top1(r: dict, n: int | None, oracle_rank: int | None = None, image_noise: float = 0.0,
                    brightness: float = 1.0, candidates: int = 1) -> bool:
    """Clean images (or exactly the perturbation ``image_noise`` / ``brightness``), SPE top-1
    (``oracle_rank``: the oracle's neighbour of that rank instead), ``candidates`` (one), N = ``n``;
    ``n=None``: the planner's default N (what an iterative method runs when not told; a one-pass
    method records None)."""
    cfg = eval_config_of(r)
    start = ("spe", 1) if oracle_rank is None else ("cheat", oracle_rank)
    images = (cfg["image_noise"], cfg["brightness"]) == (image_noise, brightness)
    return (images and (cfg["retrieval"], cfg["rank"]) == start and cfg["candidates"] == candidates
            and (cfg["N"] in (None, DEFAULT_N) if n is None else cfg["N"] == n))


def is_spe_eval(r: dict, n: int, refinement: tuple[str, int]) -> bool:
    """Whether ``r`` is a clean-image SPE top-1 evaluation at N = ``n`` with one candidate and, for
    n > 0, the refinement ``(update, rounds)``."""
    return _clean_spe_top1(r, n) and (n == 0 or _refinement(r) == tuple(refinement))


def is_eval(r: dict, method: str, n: int | None, oracle_rank: int | None = None, image_noise: float = 0.0,
            brightness: float = 1.0, refinement: tuple[str, int] | None = None, candidates: int = 1) -> bool:
    """Whether ``r`` is ``method``'s evaluation at N = ``n`` (None: the method's default) with one
    candidate (or ``candidates``), from SPE's top-1 (``oracle_rank``: the oracle's neighbour of that
    rank), on clean images (or exactly ``image_noise`` / ``brightness``), refined (n > 0) with
    ``refinement`` (update, rounds), or where None with the refinement its run's configs name (one
    round of none for a method without READ's update)."""
    if r.get("method") != method or not _clean_spe_top1(r, n, oracle_rank, image_noise, brightness, candidates):
        return False
    update, rounds = _refinement(r)
    if n == 0:
        return True
    if refinement is not None:
        return (update, rounds) == tuple(refinement)
    sde = _run_sde(r)
    if update is not None:
        return (update, rounds) == (sde.get("update"), sde.get("rounds", 1))
    # no READ update: a method whose run has an SDE (READ-O) refines its run's sde.rounds times, as
    # the planner does by default; one without (the baselines) once
    return rounds == (sde.get("rounds", 1) if (r.get("configs") or {}).get("sde") is not None else 1)


def is_default_eval(r: dict, method: str, n: int | None, oracle_rank: int | None = None,
                    image_noise: float = 0.0, brightness: float = 1.0) -> bool:
    """Whether ``r`` is what ``experiments.evaluate --run RUN [--N n]`` writes for a ``method`` run
    when told nothing else: clean images (``image_noise`` / ``brightness``: ``--noise`` /
    ``--brightness`` those), SPE top-1 (``oracle_rank``: ``--retrieval cheat --rank`` that), one
    candidate, N = ``n`` (None: the method's default) and the refinement its run's configs name."""
    return is_eval(r, method, n, oracle_rank, image_noise, brightness)


def is_direct_eval(r: dict) -> bool:
    """Whether ``r`` is a one-pass method's evaluation on clean test images (``direct``)."""
    return protocol(r) == "main" and r.get("name") == "direct"


def training_stops(r: dict) -> list[tuple[str, int | str, str]]:
    """How an evaluated run's models trained, from the record's ``training`` entry: (stage, its last
    step, why it stopped: the rule's reason, e.g. "converged" or "step cap", else "unfinished"), one
    per stage; [] where the record has none (evaluations older than the training records)."""
    return [(stage, rec.get("steps", "?"), (rec.get("stop") or {}).get("reason", "unfinished"))
            for stage, rec in (r.get("training") or {}).items()]
