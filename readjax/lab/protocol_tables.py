"""The paper's Tables 4, 5 and 8 on one READ training per task: READ refining the oracle's i-th nearest
demonstration (Table 4's READ (i), i = 1, 3, 10, at N = 100) against the same start executed unrefined
(Table 5's Cheat (i), N = 0), and READ from a poor retrieval, the oracle's 500th neighbour, at N = 0, 1
and 100 (Table 8). Ours beside the paper's row, and each refinement paired against its own start on the
same test episodes (exact McNemar, pooled over the tasks both have).

A refined cell (N > 0) takes the evaluation refined with the setting chosen on the validation split
(``chosen_on: val``) before one refined with the preset's; N = 0 does not refine.
"""

from __future__ import annotations

from readjax import tasks
from readjax.lab import main_table, paper
from readjax.lab.paired import counts, same_episodes, sign_test_p
from readjax.lab.result_record import is_eval

# (label, oracle rank, N, the paper's row, its printed averages)
ROWS = tuple(
    [row for i in (1, 3, 10) for row in (
        (f"Cheat (i = {i}), N = 0", i, 0, paper.CHEAT[i], paper.CHEAT_AVERAGES[i]),
        (f"READ (i = {i}), N = 100", i, 100, paper.TABLE4_READ[i], paper.TABLE4_READ_AVERAGES[i]))]
    + [(f"READ (i = {paper.POOR_RANK}), N = {n}", paper.POOR_RANK, n, paper.TABLE8[n], paper.TABLE8_AVERAGES[n])
       for n in (0, 1, 100)])
# refinement against its own start: (refined row, start row), by index into ROWS
PAIRS = ((1, 0), (3, 2), (5, 4), (8, 6), (7, 6))


def cell(results: list[dict], run: str, task: str, rank: int, n: int, refinement: tuple[str, int]) -> dict | None:
    """``run``'s READ evaluation on ``task`` from the oracle's ``rank``-th neighbour at N = ``n``: refined
    with the setting chosen on the validation split, else with ``refinement``; the first by file."""
    mine = sorted((r for r in results if r["_run_name"] == run and r["task"] == task), key=lambda r: r["_file"])
    if n == 0:
        return next((r for r in mine if is_eval(r, "read", 0, rank)), None)
    chosen = next((r for r in mine if main_table.is_chosen_eval(r, n, rank)), None)
    return chosen or next((r for r in mine if is_eval(r, "read", n, rank, refinement=refinement)), None)


def lines(results: list[dict], run: str, refinement: tuple[str, int]) -> list[str]:
    """The section (markdown lines) for ``run``'s protocol evaluations in ``results`` (one suite's), or []
    where it has none."""
    grid = {(k, t): cell(results, run, t, rank, n, refinement)
            for k, (_, rank, n, _, _) in enumerate(ROWS) for t in tasks.names()}
    codes = [c for c in tasks.AVG16 if any(grid[k, tasks.canonical_name(c)] for k in range(len(ROWS)))]
    if not codes:
        return []
    full = {k: [c for c in codes if grid[k, tasks.canonical_name(c)]] for k in range(len(ROWS))}
    chosen = any(r.get("chosen_on") == "val" for r in grid.values() if r)
    how = ("the setting chosen on the validation split" if chosen else
           f"{refinement[0]} x {refinement[1]} round{'s' if refinement[1] > 1 else ''}, chosen on nothing")
    out = [f"### The paper's Tables 4, 5 and 8: READ from the oracle's i-th neighbour (`{run}`)", "",
           "READ refining the i-th nearest training demonstration to the ground truth (Table 4's READ (i), N = 100) "
           "against that start executed unrefined (Table 5's Cheat (i)), and from a poor start, the 500th "
           f"neighbour (Table 8). Refined cells use {how}. Success % over "
           "the test episodes, ours over the paper's; `Avg (k)`: the k tasks the row has, the paper's over the "
           "same; Avg12 / Avg16 once a row has all their tasks.", "",
           "| row | " + " | ".join(codes) + " | Avg (k) | Avg12 | Avg16 |", "|---" * (len(codes) + 4) + "|"]
    for k, (label, _, _, theirs, printed) in enumerate(ROWS):
        ours = {c: 100.0 * grid[k, tasks.canonical_name(c)]["success_rate"] for c in full[k]}
        avg = (f"{sum(ours.values()) / len(ours):.1f} / {paper.mean_over(theirs, ours):.1f} ({len(ours)})"
               if ours else "–")
        avgs = [f"{paper.mean_over(ours, members):.1f} / {printed[name]:.1f}"
                if all(c in ours for c in members) else f"– / {printed[name]:.1f}"
                for name, members in (("Avg12", tasks.AVG12), ("Avg16", tasks.AVG16))]
        out.append(f"| {label} | " + " | ".join(f"{ours[c]:.0f} / {theirs[c]}" if c in ours else f"– / {theirs[c]}"
                                                for c in codes) + f" | {avg} | {avgs[0]} | {avgs[1]} |")
    out += ["", "Each refinement against its own start, on the same test episodes (episodes only the refined "
            "plan solves / only the start, two-sided exact p, pooled over the tasks both have):", "",
            "| refined | start | " + " | ".join(codes) + " | pooled |", "|---" * (len(codes) + 3) + "|"]
    for a, b in PAIRS:
        wins = losses = 0
        per = []
        for c in codes:
            ra, rb = grid[a, tasks.canonical_name(c)], grid[b, tasks.canonical_name(c)]
            if ra is None or rb is None or not same_episodes(ra, rb):
                per.append("–")
                continue
            w, lo, _ = counts(ra["success"], rb["success"])
            wins, losses = wins + w, losses + lo
            per.append(f"+{w} / -{lo}")
        pooled = f"+{wins} / -{losses}, p={sign_test_p(wins, losses):.2g}" if wins + losses else "–"
        out.append(f"| {ROWS[a][0]} | {ROWS[b][0]} | " + " | ".join(per) + f" | {pooled} |")
    return out + [""]
