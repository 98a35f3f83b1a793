"""The paper's claims about READ, each tested on committed results with exact paired McNemar tests.

A claim compares two evaluations on the same test episodes: READ at N = 100 against a baseline, an
ablation against the next, refinement against its own retrieval, READ from a poor retrieval, READ on
perturbed images. Which run plays which part (``ROLES``) is named by the caller (``experiments.report
--claims read=read_v3_5k deterministic=deterministic_v3_5k ...``), since ``results/`` holds many
trainings per task. Per task the table gives the discordant episodes and p; pooled over the tasks
where both sides exist (episodes paired by task and seed) it gives the verdict:

* a claim that A beats B **holds** when A wins more discordant episodes with p < 0.05, is **not
  shown** when p >= 0.05, and is **reversed** when B wins them with p < 0.05;
* a claim that A is as good as B (robustness, recovery to READ's level) **holds** unless B wins with
  p < 0.05.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from readjax import tasks
from readjax.config import preset
from readjax.lab.paired import counts, paired_outcomes
from readjax.lab.result_record import eval_config_of, is_eval, protocol, training_stops
from readjax.stage_folder import LOSS_CURVE
from readjax.tables import of_suite, suite_note

ROLES = ("read", "deterministic", "vpsde", "vpsde_cg", "read_o", "read_l", "read_o_em")
# each role is played by one method's evaluations; a role named apart from its method is a second run
# of that method (READ-O with the other sampler, Table 6)
ROLE_METHOD = {"read_o_em": "read_o"}
TOP_N = 100  # READ's N in the paper's tables (Table 7, setting A)
ALPHA = 0.05


@dataclass(frozen=True)
class Side:
    """One side of a claim: the ``role``'s run evaluated at N = ``n`` (None: the method's default),
    from SPE's top-1 or the oracle's ``rank``-th neighbour, on clean images or on images perturbed
    by ``perturbed`` ("noise" or "brightness", at whatever level the run was evaluated)."""
    role: str
    n: int | None = None
    rank: int | None = None
    perturbed: str | None = None

    def matches(self, r: dict, runs: dict[str, str], refinement: tuple[str, int] | None = None) -> bool:
        """Whether ``r`` plays this side: the role's run (``runs``), READ refined with ``refinement``
        (update, rounds; None: its run's own), the other methods as evaluated by default."""
        if r.get("_run_name") != runs.get(self.role):
            return False
        refinement = refinement if self.role == "read" else None
        method = ROLE_METHOD.get(self.role, self.role)
        if self.perturbed is None:
            return is_eval(r, method, self.n, self.rank, refinement=refinement)
        if protocol(r) != "perturbed":
            return False
        cfg = eval_config_of(r)
        noisy, dimmed = cfg["image_noise"] > 0, cfg["brightness"] != 1.0
        if (noisy, dimmed) != ((True, False) if self.perturbed == "noise" else (False, True)):
            return False
        return is_eval(r, method, self.n, self.rank, cfg["image_noise"], cfg["brightness"], refinement)


@dataclass(frozen=True)
class Claim:
    text: str
    a: Side
    b: Side
    kind: str = "better"  # "better": A > B; "level": A not below B


READ = Side("read", TOP_N)
CLAIMS = (
    Claim("READ > Deterministic", READ, Side("deterministic")),
    Claim("READ > VPSDE", READ, Side("vpsde")),
    Claim("READ > VPSDE+CG", READ, Side("vpsde_cg")),
    Claim("READ > READ-O", READ, Side("read_o")),
    Claim("READ-O > READ-L", Side("read_o"), Side("read_l")),
    # Table 6 prints READ-O with EM a little above CD on average (Avg16 60.1 / 58.8): EM as good as CD
    Claim("READ-O: EM as good as CD (Table 6)", Side("read_o_em"), Side("read_o"), "level"),
    Claim("READ > READ-O with EM", READ, Side("read_o_em")),
    Claim("refinement >> retrieval (READ N = 100 vs N = 0)", READ, Side("read", 0)),
    Claim("recovery from a poor retrieval (i = 500: N = 100 vs N = 0)", Side("read", TOP_N, 500),
          Side("read", 0, 500)),
    Claim("from i = 500, N = 100 reaches READ's level (vs SPE's start)", Side("read", TOP_N, 500), READ, "level"),
    Claim("robust to image noise (noisy vs clean images)", Side("read", TOP_N, perturbed="noise"), READ, "level"),
    Claim("robust to brightness (changed vs clean images)", Side("read", TOP_N, perturbed="brightness"), READ,
          "level"),
)


VERSION_MARK = "†"  # a task whose two sides ran on different versions of its test split


def _pick(results: list[dict], side: Side, runs: dict[str, str], refinement) -> dict[str, dict]:
    """task -> the first result (in file order) that plays ``side``."""
    out: dict[str, dict] = {}
    for r in sorted(results, key=lambda r: r.get("_file", "")):
        if side.matches(r, runs, refinement):
            out.setdefault(r["task"], r)
    return out


def verdict(kind: str, wins: int, losses: int, p: float) -> str:
    if wins + losses == 0 and kind == "better":
        return "not shown (no discordant episode)"
    if kind == "level":
        return f"does not hold (significant loss, p = {p:.2g})" if losses > wins and p < ALPHA else "holds"
    if p < ALPHA:
        return "holds" if wins > losses else "reversed"
    return f"not shown (p = {p:.2g})"


def evaluate_claims(results: list[dict], runs: dict[str, str], refinement: tuple[str, int] | None = None,
                    claims=CLAIMS) -> list[dict]:
    """Per claim: per task (code -> (wins, losses, p)), pooled (wins, losses, p) over the tasks both
    sides were measured on, and the verdict; claims with a side nobody ran are "not measured".
    READ's refined evaluations are those with ``refinement`` (update, rounds; None: its run's own)."""
    out = []
    for claim in claims:
        a, b = _pick(results, claim.a, runs, refinement), _pick(results, claim.b, runs, refinement)
        per_task, pooled_a, pooled_b, other_versions = {}, [], [], []
        for task in [t for t in tasks.names() if t in a and t in b]:
            pair = paired_outcomes(a[task], b[task])
            if pair is None:
                continue
            per_task[tasks.code_of(task)] = counts(*pair)
            if split_versions_differ(a[task], b[task]):
                other_versions.append(tasks.code_of(task))
            pooled_a.append(pair[0])
            pooled_b.append(pair[1])
        if not per_task:
            out.append({"claim": claim.text, "per_task": {}, "pooled": None, "verdict": "not measured"})
            continue
        u, v = np.concatenate(pooled_a), np.concatenate(pooled_b)
        wins, losses, p = counts(u, v)
        out.append({"claim": claim.text, "per_task": per_task, "pooled": (wins, losses, p),
                    "verdict": verdict(claim.kind, wins, losses, p),
                    "success": (100.0 * u.mean(), 100.0 * v.mean()), "other_split_versions": other_versions})
    return out


def split_versions_differ(a: dict, b: dict) -> bool:
    """Whether two evaluations paired by seed ran on different versions of the test split: the same
    seeds, so the same scenes and images, but ground-truth demos simulated on another machine or in
    another batch, which differ at float precision (contact-rich tasks; BENCHMARKS 18g). The pair is a
    fair one; the report says so rather than hiding it."""
    fa, fb = a.get("test_fingerprint"), b.get("test_fingerprint")
    return fa is not None and fb is not None and fa != fb


def training_lines(results: list[dict], runs: dict[str, str], doc_dir: Path | None = None) -> list[str]:
    """How each claimed run trained: per role and stage, grouped by why the stage stopped (the
    evaluations' ``training`` record: converged under the rule, or the step cap), each task's last
    step, linked to its loss curve (stop marked) where ``results/<task>/<run>/training/<stage>/loss.png``
    holds it (relative to ``doc_dir``, the report's folder). A baseline row counts only if its run
    converged: this is the evidence."""
    groups: dict[tuple[str, str, str], list[str]] = {}
    for role in ROLES:
        run = runs.get(role)
        picked: dict[str, dict] = {}
        for r in sorted(results, key=lambda r: r.get("_file", "")):
            if r.get("_run_name") == run and r.get("training"):
                picked.setdefault(r["task"], r)
        for task in [t for t in tasks.names() if t in picked]:
            r = picked[task]
            for stage, steps, why in training_stops(r):
                cell = f"{tasks.code_of(task)} {steps}"
                curve = Path(r["_file"]).parent.parent / "training" / stage / LOSS_CURVE
                if curve.exists():
                    cell = f"[{cell}]({os.path.relpath(curve, doc_dir) if doc_dir is not None else curve})"
                groups.setdefault((role, stage, why), []).append(cell)
    if not groups:
        return []
    return (["How each run above trained (per stage, grouped by why it stopped: each task's last step, linked "
             "to its loss curve with the stop marked where results/ holds it):", "",
             "| role | run | stage | stopped | task: steps |", "|---|---|---|---|---|"]
            + [f"| {role} | `{runs[role]}` | {stage} | {why} | {', '.join(cells)} |"
               for (role, stage, why), cells in groups.items()] + [""])


VERDICT_COLOURS = {"holds": "tab:green", "reversed": "tab:red", "does not hold": "tab:red"}  # else grey


def plot_claims(rows: list[dict], path: Path) -> bool:
    """The measured claims as a picture, a line each: pooled success of the claim's second side (open
    circle) and first side (filled), joined, coloured by the verdict (green holds, red reversed or
    does not hold, grey not shown), with the discordant counts and p. False (nothing drawn) when no
    claim was measured."""
    measured = [r for r in rows if r["pooled"] is not None]
    if not measured:
        return False
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8.5, 0.45 * len(measured) + 1.0))
    for i, row in enumerate(measured):
        y = len(measured) - 1 - i
        a, b = row["success"]
        w, l, p = row["pooled"]
        colour = next((c for k, c in VERDICT_COLOURS.items() if row["verdict"].startswith(k)), "tab:gray")
        ax.plot([b, a], [y, y], color=colour, lw=2)
        ax.plot([b], [y], "o", mfc="white", mec=colour, ms=7)
        ax.plot([a], [y], "o", color=colour, ms=7)
        ax.text(103, y, f"+{w} / -{l}, p = {p:.2g}", va="center", fontsize=7)
    ax.set_yticks(range(len(measured)), [r["claim"] for r in reversed(measured)], fontsize=7)
    ax.set_xlim(-2, 135)
    ax.set_ylim(-0.6, len(measured) - 0.4)
    ax.set_xticks(range(0, 101, 20))
    ax.set_xlabel("pooled success % (open: second side, filled: first side)")
    ax.grid(axis="x", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return True


def lines(results: list[dict], runs: dict[str, str], preset_name: str = "cpu",
          doc_dir: Path | None = None, plot: Path | None = None, suite: int = tasks.SUITE_VERSION) -> list[str]:
    """The claims section of the report (markdown lines); READ refined as preset ``preset_name`` does
    (as the main table); with ``plot``, the picture of :func:`plot_claims` there (beside the report);
    then how each named run trained (:func:`training_lines`, links relative to ``doc_dir``)."""
    unknown = sorted(set(runs) - set(ROLES))
    if unknown:
        raise ValueError(f"--claims: unknown role(s) {', '.join(unknown)}; roles are {', '.join(ROLES)}")
    results = of_suite(results, suite)
    sde = preset(preset_name)["sde"]
    rows = evaluate_claims(results, runs, (sde.update, sde.rounds))
    named = ", ".join(f"{role} = `{run}`" for role, run in runs.items())
    out = [f"## The paper's claims, tested, suite {suite}", "", suite_note(suite), "",
           f"Runs: {named}. Each claim pairs two evaluations on the same test episodes (READ at N = {TOP_N} "
           f"with the {preset_name} preset's refinement, {sde.update} x {sde.rounds} rounds, as in the main table; "
           "SPE top-1 unless an oracle rank is named); per task: episodes only the "
           "first side solves / only the second, exact McNemar p; pooled over the tasks both sides ran. "
           f"\"Better\" claims hold at p < {ALPHA}; \"level\" claims (robustness, recovery to READ's level) hold "
           "unless the first side loses significantly.", "",
           "| claim | per task | pooled success % (first / second) | pooled +/-, p | verdict |", "|---|---|---|---|---|"]
    for row in rows:
        if row["pooled"] is None:
            out.append(f"| {row['claim']} | – | – | – | {row['verdict']} |")
            continue
        cells = "; ".join(f"{code}{VERSION_MARK if code in row['other_split_versions'] else ''} +{w}/-{l} (p={p:.2g})"
                          for code, (w, l, p) in row["per_task"].items())
        w, l, p = row["pooled"]
        sa, sb = row["success"]
        out.append(f"| {row['claim']} | {cells} | {sa:.1f} / {sb:.1f} | +{w} / -{l}, p={p:.2g} | {row['verdict']} |")
    out.append("")
    if any(row.get("other_split_versions") for row in rows):
        out += [f"{VERSION_MARK} The two sides ran the same seeds (the same scenes) on different versions of the "
                "task's test split: their ground-truth demos were simulated on another machine or in another "
                "batch and differ at float precision (`test_fingerprint` in each evaluation).", ""]
    if plot is not None and plot_claims(rows, plot):
        out += [f"![the claims, pooled]({plot.name})", ""]
    return out + training_lines(results, runs, doc_dir)
