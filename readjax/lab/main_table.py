"""The paper's main table built from committed results: READ at N = 100, its own retrieval (N = 0)
and Deterministic, per task in the paper's column order with Avg12 / Avg16 and the paper's READ
beside them, then per task paired tests (READ N = 100 against N = 0 and against Deterministic).

Which runs fill the rows is named by the caller (``experiments.report --main READ_RUN DET_RUN``):
``results/`` holds many trainings per task, and the table must say which recipe it reports (several
trainings per role, comma-separated: :mod:`readjax.lab.main_table_seeds`). A READ
cell is the run's evaluation on clean test images with SPE top-1 retrieval, one candidate and the
refinement of a named preset (its ``sde.update`` and ``sde.rounds``, inference-only settings that
a run trained under an older preset can be evaluated with), so an evaluation of another inference
setting of the same run never fills it by accident. Where the run's evaluation refined with the
setting chosen on the validation split (``chosen_on: val``, the pipeline's choice step,
:mod:`readjax.lab.choice`) exists, it fills the cell instead, whatever setting was chosen.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

from readjax import failure_modes, tasks
from readjax.lab import paper
from readjax.config import preset
from readjax.lab.paired import discordant
from readjax.lab.result_record import is_direct_eval, is_eval, is_spe_eval, training_stops
from readjax.tables import of_suite, success_chart, suite_note

READ_ROW, RETRIEVAL_ROW, DET_ROW = "READ (N=100)", "retrieval only (N=0)", "Deterministic"


def refinement_of(preset_name: str) -> tuple[str, int]:
    """(update, rounds): the refinement a preset's READ plans with."""
    sde = preset(preset_name)["sde"]
    return sde.update, sde.rounds


def is_chosen_eval(r: dict, n: int, oracle_rank: int | None = None) -> bool:
    """Whether ``r`` is READ's clean-image evaluation at N = ``n`` from SPE's top-1 (``oracle_rank``: the
    oracle's neighbour of that rank) refined with the setting its choice (recorded in ``r``) picked on
    the validation split."""
    chosen = (r.get("choice") or {}).get("chosen") or {}
    return (r.get("chosen_on") == "val" and {"refine", "rounds"} <= set(chosen)
            and is_eval(r, "read", n, oracle_rank, refinement=(chosen["refine"], chosen["rounds"]),
                        candidates=chosen.get("candidates", 1)))


def select(results: list[dict], read_run: str | None, det_run: str | None,
           refinement: tuple[str, int]) -> tuple[dict[str, dict[str, dict]], list[str]]:
    """The three rows (row -> task -> result) and notes on cells that more than one file could
    fill (the first file in path order is used; for READ's row, a setting chosen on the validation
    split before the preset's). A run given as None fills its rows with nothing."""
    rows: dict[str, dict[str, dict]] = {READ_ROW: {}, RETRIEVAL_ROW: {}, DET_ROW: {}}
    notes = []
    chosen_first = sorted(results, key=lambda r: (not is_chosen_eval(r, 100), r["_file"]))
    for r in chosen_first:
        run = r["_run_name"]
        row = None
        if run == read_run and (is_chosen_eval(r, 100) or is_spe_eval(r, 100, refinement)):
            row = READ_ROW
        elif run == read_run and is_spe_eval(r, 0, refinement):
            row = RETRIEVAL_ROW
        elif run == det_run and is_direct_eval(r):
            row = DET_ROW
        if row is None:
            continue
        if r["task"] in rows[row]:
            notes.append(f"{row}, {tasks.code_of(r['task'])}: `{rows[row][r['task']]['_file']}` used, "
                         f"`{r['_file']}` also qualifies")
            continue
        rows[row][r["task"]] = r
    return rows, notes


def rates(rows: dict[str, dict[str, dict]]) -> dict[str, dict[str, float]]:
    """Row -> task code -> success % (plus Avg12 / Avg16 where all member tasks are present and
    ``Avg (k)``: the mean over the k tasks READ was measured on), with the paper's READ row last."""
    measured = [tasks.code_of(t) for t in rows[READ_ROW]]
    measured = [c for c in tasks.AVG16 if c in measured]
    out: dict[str, dict[str, float]] = {}
    for label, by_task in rows.items():
        table = {tasks.code_of(t): 100.0 * r["success_rate"] for t, r in by_task.items()}
        out[label] = with_averages(table, measured)
    out[paper.READ_LABEL] = with_averages(dict(paper.READ_TABLE7_A), measured)
    return out


def with_averages(table: dict[str, float], measured: list[str]) -> dict[str, float]:
    """``table`` (task code -> success %) with Avg12 / Avg16 where it has all their tasks and
    ``Avg (k)`` over the k codes ``measured`` where it has them all."""
    table = dict(table)
    for name, codes in (("Avg12", tasks.AVG12), ("Avg16", tasks.AVG16)):
        if all(c in table for c in codes):
            table[name] = paper.mean_over(table, codes)
    if measured and all(c in table for c in measured):
        table[f"Avg ({len(measured)})"] = paper.mean_over(table, measured)
    return table


def lines(results: list[dict], read_run: str, det_run: str, chart: Path | None = None,
          preset_name: str = "cpu", suite: int = tasks.SUITE_VERSION) -> list[str]:
    """The main table section of the report (markdown lines); ``chart``: where to draw its bars;
    READ's cells are evaluations with the refinement of preset ``preset_name``, every cell one on a
    test split of suite version ``suite`` (the same seed is another scene in another suite).
    One run name per role; several trainings per role: :func:`readjax.lab.main_table_seeds.section`."""
    results = of_suite(results, suite)
    refinement = refinement_of(preset_name)
    rows, notes = select(results, read_run, det_run, refinement)
    if not any(rows.values()):
        raise ValueError(f"--main: no evaluation of run {read_run!r} or {det_run!r} qualifies (READ: SPE top-1, "
                         f"N = 0, or N = 100 with the {preset_name} preset's refinement {refinement[0]} x "
                         f"{refinement[1]} rounds; Deterministic: 'direct')")
    table = rates(rows)
    avg_cols = [c for c in ("Avg12", "Avg16") if any(c in r for r in table.values())]
    avg_cols += sorted({c for r in table.values() for c in r if c.startswith("Avg (")})
    cols = list(tasks.AVG16) + avg_cols
    labels = {READ_ROW: f"READ (N=100): `{read_run}`", RETRIEVAL_ROW: f"retrieval only (N=0): `{read_run}`",
              DET_ROW: f"Deterministic: `{det_run}`", paper.READ_LABEL: paper.READ_LABEL}
    out = [f"## Main table (the paper's layout), suite {suite}", "", suite_note(suite), "",
           f"READ is run `{read_run}` on each task at N = 100 with the {preset_name} preset's refinement "
           f"(`sde.update={refinement[0]}`, `sde.rounds={refinement[1]}`), on clean test images "
           f"with SPE top-1 retrieval; retrieval only is the same run at N = 0; Deterministic is run `{det_run}`. "
           "Success % over each task's test episodes; – = not measured yet. Avg12 / Avg16 appear once all their "
           "tasks are measured; `Avg (k)` is the mean over the k tasks READ has been measured on, the paper's "
           "row over the same tasks.", "",
           "| method | " + " | ".join(cols) + " |", "|---" * (len(cols) + 1) + "|"]
    unverified = {(key, tasks.code_of(t)) for key, by_task in rows.items() for t, r in by_task.items()
                  if not r.get("_verified", False)}
    for key, r in table.items():
        out.append(f"| {labels[key]} | " + " | ".join(
            (f"{r[c]:.1f}" + ("‡" if (key, c) in unverified else "")) if c in r else "–" for c in cols) + " |")
    out.append("")
    if unverified:
        out += ["‡ ran on a test split with no 100 % ground-truth replay on record (`results/<task>/verify/"
                "test_<fingerprint>.json`, written by `experiments.verify --results`): not a result until it has one: "
                + ", ".join(f"{labels[k].split(':')[0]} {c}" for k, c in sorted(unverified)) + ".", ""]
    else:
        out += ["Every cell ran on a test split whose own ground truth replayed at 100 % through the evaluation "
                "path (records: `results/<task>/verify/test_<fingerprint>.json`, matched by the split's content "
                "hash).", ""]
    if chart is not None:
        success_chart({labels[k].replace("`", ""): v for k, v in table.items()}, chart)
        out += [f"![main table]({chart.name})", ""]
    out += ["Paired per task (exact McNemar on the same episodes: episodes only the first row solves / only "
            "the second, two-sided p):", "",
            "| task | READ N=100 vs N=0 | READ N=100 vs Deterministic |", "|---|---|---|"]
    for code in tasks.AVG16:
        task = tasks.canonical_name(code)
        read = rows[READ_ROW].get(task)
        if read is None:
            continue
        cells = [discordant(read, other[task]) if task in other else "–" for other in (rows[RETRIEVAL_ROW], rows[DET_ROW])]
        out.append(f"| {code} | " + " | ".join(cells) + " |")
    out.append("")
    out += failure_lines({labels[k]: rows[k] for k in (READ_ROW, DET_ROW)})
    out += training_lines({labels[k]: v for k, v in rows.items()})
    out += media_lines(rows[READ_ROW], chart.parent if chart is not None else None)
    if notes:
        out += ["Cells more than one evaluation could fill:", ""] + [f"- {n}" for n in notes] + [""]
    return out


def failure_lines(rows: dict[str, dict[str, dict]]) -> list[str]:
    """The rows' failures per task counted by mode (the evaluation's ``failures`` record, see
    :mod:`readjax.failure_modes`); for a method that refines a retrieved motion, how many failures
    started from a retrieval a wrong place away; and the median worst key-frame error of failed
    and of successful episodes. Tasks whose evaluation predates the record are left out."""
    fmt = lambda x: "–" if x is None else f"{x:.1f}"  # noqa: E731
    body = []
    for code in tasks.AVG16:
        for label, by_task in rows.items():
            r = by_task.get(tasks.canonical_name(code))
            if r is None or "failures" not in r:
                continue
            f = r["failures"]
            med = f["median_keyframe_error_cm"]
            rot = failure_modes.median_by_outcome(f["keyframe_rotation_deg"], r["success"])
            failed = len(r["success"]) - sum(r["success"])
            wrong_start = f.get("failed_from_a_wrong_start")
            body.append(f"| {code} | {label} | {failed} | " + " | ".join(str(f["counts"].get(m, 0) or "")
                        for m in failure_modes.MODES) + f" | {'–' if wrong_start is None else wrong_start} | "
                        f"{fmt(med['failed'])} / {fmt(med['succeeded'])} | {fmt(rot['failed'])} / {fmt(rot['succeeded'])} |")
    if not body:
        return []
    f0 = next(r["failures"] for by_task in rows.values() for r in by_task.values() if "failures" in r)
    return ["Failures by mode (the first that applies, left to right; key frames: where the demonstration opens "
            f"or closes the gripper, and its end; off: beyond {f0['tolerance_cm']:g} cm or "
            f"{f0['tolerance_deg']:g} degrees):", ""] + [
            f"- *{m}*: {failure_modes.MODE_HELP[m]}" for m in failure_modes.MODES] + [
            f"- *from a wrong start*: failures whose retrieved motion (where refinement started) was already "
            f"more than {100 * failure_modes.WRONG_PLACE_M:g} cm off at a key frame", "",
            "| task | row | failed | " + " | ".join(failure_modes.MODES)
            + " | from a wrong start | worst key-frame error, cm (median: failed / succeeded) "
            "| orientation error, degrees (median: failed / succeeded) |",
            "|---" * (len(failure_modes.MODES) + 6) + "|"] + body + [""]


def training_lines(rows: dict[str, dict[str, dict]]) -> list[str]:
    """How long each row's models trained and why they stopped (the results' ``training`` record):
    per stage the step counts and reasons over the row's tasks, e.g. ``read 5000 (step cap) x 4``."""
    out = ["How the rows' models trained (per stage: steps, why it stopped, on how many tasks):", ""]
    for label, by_task in rows.items():
        counts: dict[str, int] = {}
        missing = 0
        for r in by_task.values():
            stops = training_stops(r)
            missing += not stops
            for stage, steps, why in stops:
                key = f"{stage} {steps} ({why})"
                counts[key] = counts.get(key, 0) + 1
        parts = [f"{k} x {n}" for k, n in sorted(counts.items())]
        if missing:
            parts.append(f"not recorded x {missing}")
        if parts:
            out.append(f"- {label}: " + "; ".join(parts))
    return out + [""]


MEDIA_EPISODES_BEFORE_RECORD = 8  # what the pipeline rendered before it published the media JSON


def shown_outcomes(media_json: Path, cell: dict) -> list[bool]:
    """The outcomes of the episodes a task's overlay and video show, in the cell's evaluation: the
    rendered evaluation's seeds, read from its JSON beside the pictures; media published before
    the JSON was are the pipeline's default first 8 episodes."""
    if media_json.exists():
        outcomes = dict(zip(cell.get("seeds", []), cell["success"]))
        seeds = json.loads(media_json.read_text()).get("seeds", [])
        if seeds and all(s in outcomes for s in seeds):
            return [outcomes[s] for s in seeds]
    return cell["success"][:MEDIA_EPISODES_BEFORE_RECORD]


def media_lines(read_cells: dict[str, dict], doc_dir: Path | None, whose: str | None = None) -> list[str]:
    """READ's rendered episodes per task, where the pipeline made them: the first test episodes of
    the evaluation that fills the READ cell, rendered again under the same name in the run's
    ``media/`` folder beside ``eval/`` (motion overlay, linked rollout video). Paths are relative to
    ``doc_dir``, the folder of the report that shows them; ``whose``: the run the cells are of, where
    the table shows several READ trainings."""
    out = []
    for code in tasks.AVG16:
        r = read_cells.get(tasks.canonical_name(code))
        if r is None:
            continue
        media = Path(r["_file"]).parent.parent / "media"
        overlay, video = media / f"{r['name']}_overlay.png", media / f"{r['name']}_rollouts.mp4"
        if not overlay.exists():
            continue
        link = lambda f: Path(os.path.relpath(f.resolve(), doc_dir.resolve())).as_posix() if doc_dir else f.as_posix()  # noqa: E731
        ok = shown_outcomes(media / f"{r['name']}.json", r)
        head = f"**{code}** ({tasks.canonical_name(code)}): the first {len(ok)} test episodes, {sum(ok)} succeeded"
        out += [head + (f"; [rollout video]({link(video)})" if video.exists() else "") + ".", "",
                f"![{code}: retrieved, planned and ground-truth motions]({link(overlay)})", ""]
    if out:
        out = ["### READ's plans and rollouts per task", "",
               "Each overlay shows a task's first test images with the retrieved (yellow), planned (blue) "
               "and ground-truth (green) paths of the end effector, a dot where the gripper is closed; the "
               "video executes the first four plans. Outcomes as in the table"
               + (f"'s row of training `{whose}`." if whose else "."), ""] + out
    return out

