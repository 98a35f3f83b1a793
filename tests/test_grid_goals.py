"""The goals of the current suite's table (readjax.lab.grid_goals) and the averages they read
(main_table_seeds.summary): an average over tasks where other seeds run on fewer tasks, goals pending
until every training has every task it is planned on, then met or missed by the numbers."""

import math

from readjax import tasks
from readjax.lab import grid_goals
from readjax.lab import main_table as mt
from readjax.lab import main_table_seeds as seeds

EPISODES = list(range(20))


def _result(wins: int, suite: int = 2) -> dict:
    """A result on 20 episodes that the first ``wins`` of them solve."""
    success = [k < wins for k in EPISODES]
    return {"success": success, "success_rate": wins / len(EPISODES), "seeds": EPISODES, "suite": suite,
            "_file": f"fake_{wins}.json"}


def _trainings(read: dict[str, dict[str, int]], ret: dict[str, dict[str, int]],
               det: dict[str, dict[str, int]]) -> seeds.Trainings:
    """Row -> [(run, task -> result)] from run -> task code -> episodes won (of 20)."""
    def row(runs):
        return [(run, {tasks.canonical_name(c): _result(w) for c, w in by_code.items()}) for run, by_code in runs.items()]
    return {mt.READ_ROW: row(read), mt.RETRIEVAL_ROW: row(ret), mt.DET_ROW: row(det)}


EIGHT = ("PC", "RT", "PB", "OW", "CB", "PH", "PK", "PU")
PLAN = {"r0": tasks.AVG16, "r1": EIGHT, "d0": tasks.AVG16, "d1": EIGHT}


def test_an_average_over_task_means_where_another_seed_covers_fewer_tasks():
    read = {"r0": {c: 18 for c in tasks.AVG16}, "r1": {c: 10 for c in EIGHT}}
    means = seeds.summary(_trainings(read, read, read), [])[mt.READ_ROW]
    # the eight shared tasks average (90 + 50) / 2 = 70, the other eight 90: Avg16 = 80, not r0's own 90
    mean, lo, hi, k = means["Avg16"]
    assert (mean, k) == (80.0, 0) and math.isnan(lo) and math.isnan(hi)
    assert seeds.spread(*means["Avg16"], 2) == "80.0§"
    assert means["PC"][:4] == (70.0, 50.0, 90.0, 2)
    # once every training has every task, the mean of the trainings' own averages, with its range
    full = {"r0": {c: 18 for c in tasks.AVG16}, "r1": {c: 10 for c in tasks.AVG16}}
    means = seeds.summary(_trainings(full, full, full), [])[mt.READ_ROW]
    assert means["Avg16"] == (70.0, 50.0, 90.0, 2) and seeds.spread(*means["Avg16"], 2) == "70.0 (50-90)"
    # a task no training has: no average at all
    gap = {"r0": {c: 18 for c in tasks.AVG16 if c != "SB"}, "r1": {c: 10 for c in EIGHT}}
    assert "Avg16" not in seeds.summary(_trainings(gap, gap, gap), [])[mt.READ_ROW]


def _by_goal(rows):
    return {g["goal"].split(" (")[0]: g for g in rows}


def test_goals_stay_pending_until_every_planned_task_is_measured():
    read = {"r0": {c: 19 for c in tasks.AVG16}, "r1": {c: 19 for c in EIGHT if c != "PU"}}
    goals = _by_goal(grid_goals.goals(_trainings(read, read, {"d0": {}, "d1": {}}), PLAN))
    assert goals["READ Avg16 ≥ 70"]["verdict"] == "pending"
    assert goals["READ Avg16 ≥ 70"]["so_far"] == "`r0` 16/16 tasks, `r1` 7/8 tasks"
    assert goals["READ N = 100 above Deterministic, pooled"]["so_far"] == "0 of 24 task x training pairs"
    assert goals["PU: refinement above retrieval"]["verdict"] == "pending"
    assert goals["PU: refinement above retrieval"]["so_far"] == "1 of 2 trainings"
    assert goals["BB: refinement above retrieval"]["so_far"] == "1 of 1 training"  # BB: seed 0 only
    assert goals["BB: refinement above retrieval"]["verdict"] == "missed"  # equal outcomes: no discordant episode


def test_goals_met_and_missed_by_the_numbers():
    read = {"r0": {c: 18 for c in tasks.AVG16}, "r1": {c: 18 for c in EIGHT}}
    ret = {"r0": {c: (4 if c == "OW" else 18) for c in tasks.AVG16}, "r1": {c: (4 if c == "OW" else 18) for c in EIGHT}}
    det = {"d0": {c: 12 for c in tasks.AVG16}, "d1": {c: 12 for c in EIGHT}}
    goals = _by_goal(grid_goals.goals(_trainings(read, ret, det), PLAN))
    assert goals["READ Avg12 ≥ 85"]["verdict"] == "met" and goals["READ Avg12 ≥ 85"]["measured"] == "90.0§"
    vs = goals["READ N = 100 above Deterministic, pooled"]
    assert vs["verdict"] == "met" and vs["measured"].startswith("+144 / -0, p=")  # 24 pairs x 6 episodes
    assert vs["measured"].endswith(", 24 pairs; 90.0 / 60.0 %")  # each side's success over the pairs used
    assert vs["so_far"] == "24 of 24 task x training pairs"
    ow = goals["OW: refinement above retrieval"]
    assert ow["verdict"] == "met" and ow["measured"].startswith("+28 / -0")  # 14 episodes in each of 2 pairs
    assert goals["PK: refinement above retrieval"]["verdict"] == "missed"  # level: no episode between them
    # a recipe below the goal misses it, however complete
    low = {"r0": {c: 12 for c in tasks.AVG16}, "r1": {c: 12 for c in EIGHT}}
    goals = _by_goal(grid_goals.goals(_trainings(low, ret, det), PLAN))
    assert goals["READ Avg16 ≥ 70"]["verdict"] == "missed" and goals["READ Avg16 ≥ 70"]["measured"] == "60.0§"
    assert goals["READ N = 100 above Deterministic, pooled"]["verdict"] == "missed"


def test_pairs_on_other_episodes_keep_a_goal_pending():
    read = {"r0": {"OW": 18}}
    trainings = _trainings(read, {"r0": {"OW": 4}}, {"d0": {}})
    trainings[mt.RETRIEVAL_ROW][0][1]["open_wine"]["seeds"] = [e + 100 for e in EPISODES]
    ow = _by_goal(grid_goals.goals(trainings, {"r0": ("OW",)}))["OW: refinement above retrieval"]
    assert ow["verdict"] == "pending" and ow["measured"] == "–" and ow["so_far"] == "0 of 1 training"


def test_the_readme_line_counts_the_goals_and_names_the_decided_ones():
    from readjax.lab import readme_tables
    read = {"r0": {c: 18 for c in tasks.AVG16}, "r1": {c: 18 for c in EIGHT}}
    ret = {"r0": {c: (4 if c == "OW" else 18) for c in tasks.AVG16}, "r1": {c: (4 if c == "OW" else 18) for c in EIGHT}}
    det = {"d0": {c: 12 for c in tasks.AVG16}, "d1": {c: 12 for c in EIGHT if c != "PU"}}  # one pair still running
    line = readme_tables.goals_line(_trainings(read, ret, det), PLAN)
    verdicts = [g["verdict"] for g in grid_goals.goals(_trainings(read, ret, det), PLAN)]
    assert (verdicts.count("met"), verdicts.count("missed"), verdicts.count("pending")) == (3, 5, 1)
    assert "3 met, 5 missed, 1 pending until every training has its tasks (met: READ Avg12 ≥ 85, READ Avg16 ≥ 70, " \
           "OW: refinement above retrieval; missed: PC: refinement above retrieval, PH: " in line
