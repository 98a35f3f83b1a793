"""The current suite's main table held against the paper's: the goals a reader checks first.

Three kinds of goal, each measured on the trainings of a grid (one per ``train.seed``, cells chosen as
:func:`readjax.lab.main_table_seeds.select_trainings` chooses them):

- READ's Avg12 and Avg16 at N = 100, as the main table averages them (:func:`main_table_seeds.summary`:
  over trainings, or over the task means where other seeds run on fewer tasks), at least :data:`AVG_GOALS`
  (the paper's 88.8 / 70.2 rounded down to a round goal);
- READ above Deterministic, one exact McNemar test pooled over every task and every training pair;
- refinement above retrieval (READ N = 100 against N = 0 of the same training), pooled over trainings,
  on each task of :data:`REFINEMENT_TASKS`, where the paper's refinement rose far above its retrieval.

A goal is *met* or *missed* only once every training has every task it is planned on (``plan``: run ->
task codes; every task where a run is not named); before that it is *pending* and the line shows what is
measured so far.
"""

from __future__ import annotations

from collections.abc import Mapping

from readjax import tasks
from readjax.lab import main_table as mt
from readjax.lab import main_table_seeds as seeds
from readjax.lab import paper
from readjax.lab import paired
from readjax.lab.paired import sign_test_p

AVG_GOALS = {"Avg12": 85.0, "Avg16": 70.0}
# where the paper's READ at N = 100 (Table 7 A) rose far above its retrieval alone (Table 5, N = 0):
# OW +51, PK +48, PC +23, PH +20, PU +17, BB +13 points (issue 52's list)
REFINEMENT_TASKS = ("PC", "OW", "PH", "BB", "PK", "PU")
ALPHA = 0.05
Plan = Mapping[str, tuple[str, ...]]  # run -> the task codes it is planned on


def planned(plan: Plan, run: str, codes=tasks.AVG16) -> list[str]:
    """The tasks of ``codes`` that ``run`` is planned on (all of them where ``plan`` does not name it)."""
    return [c for c in codes if c in plan.get(run, tasks.AVG16)]


def paired_verdict(wins: int, losses: int, complete: bool) -> str:
    """``met`` where the first side won more pairs at p < :data:`ALPHA`, else ``missed``; ``pending`` while
    ``complete`` is false."""
    if not complete:
        return "pending"
    return "met" if wins > losses and sign_test_p(wins, losses) < ALPHA else "missed"


def pooled(pairs: list[tuple[dict, dict]]) -> tuple[int, int, int, str]:
    """(wins, losses, pairs used, text) of result pairs (a, b) pooled on their common episodes
    (:func:`paired.pooled`): the text ``+w / -l, p=..., k pairs; a / b %`` with the success of each
    side over the pairs used, or ``–`` where no pair ran the same episodes."""
    wins, losses, left_out, text = paired.pooled(pairs)
    used = [pair for k, pair in enumerate(pairs) if k not in left_out]
    if not used:
        return wins, losses, 0, text
    a, b = (100 * sum(pair[i]["success_rate"] for pair in used) / len(used) for i in (0, 1))
    return wins, losses, len(used), f"{text}; {a:.1f} / {b:.1f} %"


def average_goals(trainings: seeds.Trainings, plan: Plan) -> list[dict]:
    """Avg12 / Avg16 of READ at N = 100, as the main table computes them (:func:`seeds.summary`)."""
    reads = trainings[mt.READ_ROW]
    means = seeds.summary({mt.READ_ROW: reads}, [])[mt.READ_ROW]
    out = []
    for name, codes in (("Avg12", tasks.AVG12), ("Avg16", tasks.AVG16)):
        have = {run: [c for c in planned(plan, run, codes) if tasks.canonical_name(c) in cells] for run, cells in reads}
        complete = bool(reads) and all(len(have[run]) == len(planned(plan, run, codes)) for run, _ in reads)
        measured = seeds.spread(*means[name], len(reads)) if name in means else "–"
        verdict = ("met" if means[name][0] >= AVG_GOALS[name] else "missed") if complete and name in means else "pending"
        progress = ", ".join(f"`{run}` {len(have[run])}/{len(planned(plan, run, codes))} tasks" for run, _ in reads)
        out.append({"goal": f"READ {name} ≥ {AVG_GOALS[name]:.0f} (the paper: {paper.READ_TABLE7_A_AVERAGES[name]})",
                    "measured": measured, "verdict": verdict, "so_far": progress})
    return out


def pairs_of(first: list, second: list, task: str) -> list[tuple[dict, dict]]:
    """The i-th training of one row against the i-th of another on ``task``, where both have it."""
    return [(a[task], b[task]) for (_, a), (_, b) in zip(first, second) if task in a and task in b]


def versus_goal(trainings: seeds.Trainings, plan: Plan) -> dict:
    """READ N = 100 above Deterministic, pooled over every task and every training pair."""
    reads, dets = trainings[mt.READ_ROW], trainings[mt.DET_ROW]
    pairs = [p for code in tasks.AVG16 for p in pairs_of(reads, dets, tasks.canonical_name(code))]
    wins, losses, used, text = pooled(pairs)
    need = sum(len(set(planned(plan, r)) & set(planned(plan, d))) for (r, _), (d, _) in zip(reads, dets))
    return {"goal": "READ N = 100 above Deterministic, pooled (paired, p < 0.05)", "measured": text,
            "verdict": paired_verdict(wins, losses, used == need == len(pairs)),
            "so_far": f"{used} of {need} task x training pairs"}


def refinement_goals(trainings: seeds.Trainings, plan: Plan) -> list[dict]:
    """Per task of :data:`REFINEMENT_TASKS`: READ N = 100 above N = 0, pooled over trainings."""
    reads, rets = trainings[mt.READ_ROW], trainings[mt.RETRIEVAL_ROW]
    out = []
    for code in REFINEMENT_TASKS:
        task = tasks.canonical_name(code)
        pairs = pairs_of(reads, rets, task)
        wins, losses, used, text = pooled(pairs)
        need = sum(code in planned(plan, run) for run, _ in reads)
        gain = paper.READ_TABLE7_A[code] - paper.RETRIEVAL_ONLY[code]
        out.append({"goal": f"{code}: refinement above retrieval (the paper: {paper.READ_TABLE7_A[code]} / "
                            f"{paper.RETRIEVAL_ONLY[code]} %, +{gain})", "measured": text,
                    "verdict": paired_verdict(wins, losses, used == need == len(pairs) and need > 0),
                    "so_far": f"{used} of {need} training{'s' if need != 1 else ''}"})
    return out


def goals(trainings: seeds.Trainings, plan: Plan | None = None) -> list[dict]:
    """Every goal's row: goal, measured, verdict (met / missed / pending), so_far."""
    plan = plan or {}
    return average_goals(trainings, plan) + [versus_goal(trainings, plan)] + refinement_goals(trainings, plan)


def lines(trainings: seeds.Trainings, plan: Plan | None = None) -> list[str]:
    """The goals table (markdown lines), for :func:`readjax.lab.main_table_seeds.lines`'s ``goals``."""
    out = ["The goals (issue 52), held against the paper's READ: Avg12 / Avg16 as in the table above; the paired "
           "tests pool the discordant episodes of every training pair (exact McNemar; READ's i-th training "
           "against Deterministic's i-th, READ N = 100 against N = 0 of the same training), success % of the "
           "first side / the second after the counts. A goal is met or missed once every training has every "
           "task it needs, pending until then. Where one is missed, the failures by mode below give the reason "
           "per task.", "",
           "| goal | measured | verdict | measured so far |", "|---|---|---|---|"]
    out += [f"| {g['goal']} | {g['measured']} | {g['verdict']} | {g['so_far']} |" for g in goals(trainings, plan)]
    return out + [""]
