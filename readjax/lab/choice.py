"""Choosing READ's refinement setting on the validation split, and the record of that choice.

A READ run is evaluated on the validation split (``experiments.evaluate --split val``: seeds from
2,000,000, disjoint from the training and test seeds; records in ``RUN/val/``, copied to
``results/<task>/<run>/val/``, never in an ``eval/`` folder that a table reads) once per refinement
setting of the grid's ``ChoiceGrid``. :func:`choose` keeps the setting with the highest val success
(:data:`RULE`), and the choice file ``results/<task>/<run>/choice.json`` (:func:`make_choice`) records
it with every candidate's val outcome, the val split's fingerprint and the commit. The run's test
evaluations then refine with the chosen setting (``experiments.evaluate --choice FILE``) and name the
file (:func:`record_of`): no setting is picked by looking at the test episodes.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Sequence
from pathlib import Path

from readjax import atomic_write, provenance
from readjax.lab import result_record, verification
from readjax.lab.refine_setting import PAPER_SETTING, RefineSetting

FILE = "choice.json"
VAL_FOLDER = "val"  # RUN/val/ and results/<task>/<run>/val/: the val evaluations, apart from eval/
RULE = ("the highest success rate on the validation split; ties go to the setting closest to the paper's "
        "recipe (rounds 1, renoise, candidates 1): fewest fields that differ from it, then fewest extra "
        "rounds and candidates, then the grid's order")


def choice_path(results: str | Path, task: str, run_name: str) -> Path:
    return Path(results) / task / run_name / FILE


def departures(setting: RefineSetting) -> tuple[int, int]:
    """How far ``setting`` is from the paper's recipe: the fields that differ, then the extra rounds
    and candidates."""
    s, p = setting, PAPER_SETTING
    differ = (s.rounds != p.rounds) + (s.refine != p.refine) + (s.candidates != p.candidates)
    return differ, abs(s.rounds - p.rounds) + abs(s.candidates - p.candidates)


def choose(outcomes: Sequence[tuple[RefineSetting, float]]) -> RefineSetting:
    """The setting with the highest val success rate among ``(setting, rate)`` (in the grid's order);
    ties broken by :data:`RULE`."""
    if not outcomes:
        raise ValueError("nothing to choose from: no candidate setting")
    order = {s: i for i, (s, _) in reversed(list(enumerate(outcomes)))}
    return min(outcomes, key=lambda o: (-o[1], *departures(o[0]), order[o[0]]))[0]


def is_val_eval(r: dict, results: str | Path, task: str, setting: RefineSetting, n: int,
                episodes: int) -> bool:
    """Whether ``r`` is READ's evaluation of ``episodes`` val episodes of ``task`` at N = ``n`` refined
    with ``setting``, on a val split whose ground-truth replay is on record at 100 % under ``results``."""
    return (r.get("split") == "val" and r.get("task") == task and r.get("episodes") == episodes
            and result_record.is_eval(r, "read", n, refinement=(setting.refine, setting.rounds),
                                      candidates=setting.candidates)
            and verification.is_verified(results, task, r.get("test_fingerprint"), episodes, split="val"))


def val_records(results: str | Path, task: str, run_name: str, setting: RefineSetting, n: int,
                episodes: int) -> list[tuple[Path, dict]]:
    """(path, record) of each val evaluation of ``setting`` in ``results/<task>/<run>/val/``."""
    out = []
    for f in sorted((Path(results) / task / run_name / VAL_FOLDER).glob("*.json")):
        try:
            r = json.loads(f.read_text())
        except json.JSONDecodeError:
            continue
        if isinstance(r, dict) and is_val_eval(r, results, task, setting, n, episodes):
            out.append((f, r))
    return out


def make_choice(results: str | Path, task: str, run_name: str, settings: Sequence[RefineSetting], n: int,
                episodes: int) -> dict:
    """The choice among ``settings`` from their val evaluations under ``results`` (one each, all on
    one version of the val split), as the choice file holds it."""
    found = {s: val_records(results, task, run_name, s, n, episodes) for s in settings}
    missing = [s.text() for s, recs in found.items() if not recs]
    folder = Path(results) / task / run_name / VAL_FOLDER
    if missing:
        raise ValueError(f"{task}/{run_name}: no evaluation of {episodes} val episodes at N = {n} on a "
                         f"verified val split for {'; '.join(missing)} (experiments.evaluate --split val, "
                         f"its JSON copied to {folder})")
    common = set.intersection(*({r["test_fingerprint"] for _, r in recs} for recs in found.values()))
    if not common:
        raise ValueError(f"{task}/{run_name}: the candidates' val evaluations ran on different versions of "
                         f"the val split (another machine's float rounding): remove {folder} and evaluate "
                         f"them again on one machine")
    fingerprint = min(common)
    picked = {s: next((f, r) for f, r in found[s] if r["test_fingerprint"] == fingerprint) for s in settings}
    chosen = choose([(s, picked[s][1]["success_rate"]) for s in settings])
    return {
        "task": task, "run": run_name, "method": "read", "split": "val", "N": n, "episodes": episodes,
        "val_fingerprint": fingerprint, "chosen": dataclasses.asdict(chosen), "flags": chosen.argv(),
        "rule": RULE,
        "candidates": [{"setting": dataclasses.asdict(s), "success_rate": r["success_rate"],
                        "successes": int(sum(r.get("success", []))), "episodes": r["episodes"],
                        "record": str(f)} for s, (f, r) in picked.items()],
        "commit": provenance.commit(),
    }


def write_choice(results: str | Path, choice: dict) -> Path:
    path = choice_path(results, choice["task"], choice["run"])
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write.write_text(path, json.dumps(choice, indent=2), tmp_name=f".{FILE}.tmp")
    return path


def load(path: str | Path) -> dict | None:
    """A choice file, or None where there is none (missing, unreadable, or another kind of record)."""
    try:
        c = json.loads(Path(path).read_text())
    except (FileNotFoundError, json.JSONDecodeError):
        return None
    return c if isinstance(c, dict) and "chosen" in c and "candidates" in c else None


def chosen_setting(choice: dict) -> RefineSetting:
    return RefineSetting(**choice["chosen"])


def finished_choice(results: str | Path, task: str, run_name: str, settings: Sequence[RefineSetting], n: int,
                    episodes: int) -> dict | None:
    """The choice file of that run if it chose among exactly ``settings`` at N = ``n`` on ``episodes``
    val episodes of a val split whose replay is on record at 100 % (the version it names, its
    fingerprint): such a choice is not made again."""
    c = load(choice_path(results, task, run_name))
    if c is None or c.get("N") != n or c.get("episodes") != episodes:
        return None
    try:
        theirs = {RefineSetting(**x["setting"]) for x in c["candidates"]}
    except (KeyError, TypeError, ValueError):
        return None
    verified = verification.is_verified(results, task, c.get("val_fingerprint"), episodes, split="val")
    if theirs != set(settings) or not verified:
        return None
    return c


def record_of(path: str | Path, choice: dict) -> dict:
    """What an evaluation refined with a choice records of it."""
    keep = ("chosen", "N", "episodes", "val_fingerprint", "rule", "commit")
    return {"chosen_on": "val", "choice": {"file": str(path), **{k: choice.get(k) for k in keep}}}


def is_chosen_eval(r: dict, method: str, path: str | Path, n: int | None, oracle_rank: int | None = None,
                   image_noise: float = 0.0, brightness: float = 1.0) -> bool:
    """Whether ``r`` is ``method``'s evaluation at N = ``n`` (start and images as in
    ``result_record.is_eval``) refined with the setting the choice file ``path`` holds, and says so.
    N = 0 refines nothing: the run's evaluation at N = 0, chosen or not. No choice file: False."""
    if n == 0:
        return result_record.is_eval(r, method, 0, oracle_rank, image_noise, brightness)
    c = load(path)
    if c is None:
        return False
    s = chosen_setting(c)
    return r.get("chosen_on") == "val" and result_record.is_eval(
        r, method, n, oracle_rank, image_noise, brightness, refinement=(s.refine, s.rounds),
        candidates=s.candidates)
