"""The paper's claims, tested on results: which evaluation plays each side, pooled paired tests,
and the verdicts (holds / not shown / reversed; level claims hold unless the first side loses)."""

from __future__ import annotations

import json

import pytest

from experiments import _cli
from experiments import report as report_cli
from readjax import tasks
from readjax.lab import claims
from readjax.config import preset

SDE = preset("cpu")["sde"]


def _result(task, run, method, success, n=100, rank=None, noise=0.0, brightness=1.0, rounds=None, name=None):
    read = method == "read"
    cfg = {"N": n, "retrieval": "spe" if rank is None else "cheat", "rank": rank or 1, "candidates": 1,
           "image_noise": noise, "brightness": brightness,
           "rounds": (SDE.rounds if rounds is None else rounds) if read else 1,
           "refine_update": SDE.update if read else None}
    name = name or f"{method}_{n}_{rank}_{noise}_{brightness}_{rounds}"
    return {"task": task, "method": method, "name": name, "_run_name": run, "_file": f"{task}/{run}/{name}.json",
            "seeds": list(range(len(success))), "success": list(success), "success_rate": sum(success) / len(success),
            "episodes": len(success), "eval_config": cfg, "suite": tasks.SUITE_VERSION,
            "configs": {"sde": {"update": "cold", "rounds": 1}} if read else {"resnet": {}}}


def _by_claim(rows):
    return {r["claim"]: r for r in rows}


def test_read_against_a_baseline_pooled_over_tasks():
    runs = {"read": "r", "deterministic": "d"}
    results = [
        _result("reach_target", "r", "read", [1] * 20),
        _result("reach_target", "d", "deterministic", [0] * 12 + [1] * 8, n=None),
        _result("push_button", "r", "read", [1] * 10),
        _result("push_button", "d", "deterministic", [1] * 10, n=None),
        # another refinement of the same run (the run's own, an older preset): not READ's cell
        _result("push_button", "r", "read", [0] * 10, rounds=1, name="old"),
    ]
    rows = _by_claim(claims.evaluate_claims(results, runs, (SDE.update, SDE.rounds)))
    row = rows["READ > Deterministic"]
    assert row["per_task"] == {"RT": (12, 0, pytest.approx(2 * 0.5 ** 12)), "PB": (0, 0, 1.0)}
    assert row["pooled"][:2] == (12, 0) and row["verdict"] == "holds"
    assert row["success"] == (100.0, pytest.approx(60.0))
    assert rows["READ > VPSDE"]["verdict"] == "not measured"
    swapped = _by_claim(claims.evaluate_claims(results, {"read": "d", "deterministic": "r"}))
    assert swapped["READ > Deterministic"]["verdict"] == "not measured"  # run d holds no READ evaluation


def test_a_pair_across_versions_of_a_test_split_is_kept_and_marked():
    """Two sides run on the same seeds but on test splits simulated apart (fingerprints differ): the
    same scenes, so the pair counts; the report marks the task and says why. Same version, or a
    result that records none: no mark."""
    runs = {"read": "r", "deterministic": "d"}
    results = [_result("reach_target", "r", "read", [1] * 10), _result("reach_target", "d", "deterministic", [0] * 10, n=None),
               _result("push_button", "r", "read", [1] * 4), _result("push_button", "d", "deterministic", [1] * 4, n=None)]
    for r, fp in zip(results, ["aaaa", "bbbb", "cccc", "cccc"]):
        r["test_fingerprint"] = fp
    row = _by_claim(claims.evaluate_claims(results, runs, (SDE.update, SDE.rounds)))["READ > Deterministic"]
    assert row["per_task"]["RT"][:2] == (10, 0) and row["other_split_versions"] == ["RT"]
    text = "\n".join(claims.lines(results, runs))
    assert f"RT{claims.VERSION_MARK} +10/-0" in text and f"PB{claims.VERSION_MARK}" not in text
    assert "different versions" in text
    del results[1]["test_fingerprint"]
    assert "different versions" not in "\n".join(claims.lines(results, runs))


def test_verdicts():
    assert claims.verdict("better", 12, 0, 0.0005) == "holds"
    assert claims.verdict("better", 0, 12, 0.0005) == "reversed"
    assert claims.verdict("better", 3, 1, 0.62).startswith("not shown")
    assert claims.verdict("better", 0, 0, 1.0).startswith("not shown")
    assert claims.verdict("level", 1, 3, 0.62) == "holds"  # a loss within noise: level
    assert claims.verdict("level", 0, 12, 0.0005).startswith("does not hold")


def test_poor_retrieval_and_perturbed_images():
    runs = {"read": "r"}
    clean = [1] * 30
    results = [
        _result("reach_target", "r", "read", clean),
        _result("reach_target", "r", "read", [1] * 29 + [0], rank=500),
        _result("reach_target", "r", "read", [0] * 30, n=0, rank=500),
        _result("reach_target", "r", "read", [1] * 28 + [0] * 2, noise=0.05),
        _result("reach_target", "r", "read", [0] * 15 + [1] * 15, brightness=0.7),
        _result("reach_target", "r", "read", [0] * 30, noise=0.05, brightness=0.7),  # both at once: neither row
    ]
    rows = _by_claim(claims.evaluate_claims(results, runs, (SDE.update, SDE.rounds)))
    assert rows["recovery from a poor retrieval (i = 500: N = 100 vs N = 0)"]["verdict"] == "holds"
    assert rows["from i = 500, N = 100 reaches READ's level (vs SPE's start)"]["verdict"] == "holds"
    assert rows["robust to image noise (noisy vs clean images)"]["pooled"][:2] == (0, 2)
    assert rows["robust to image noise (noisy vs clean images)"]["verdict"] == "holds"
    assert rows["robust to brightness (changed vs clean images)"]["verdict"].startswith("does not hold")


def test_cli_section_and_bad_roles(tmp_path, capsys):
    root = tmp_path / "results"
    for r in (_result("reach_target", "r5", "read", [1] * 10), _result("reach_target", "r5", "read", [0] * 10, n=0)):
        d = root / r["task"] / r["_run_name"] / "eval"
        d.mkdir(parents=True, exist_ok=True)
        (d / f"{r['name']}.json").write_text(json.dumps({k: v for k, v in r.items() if not k.startswith("_")}))
    out = tmp_path / "report.md"
    assert _cli.run(report_cli.main, ["--runs", str(root), "--out", str(out), "--claims", "read=r5"]) == 0
    text = out.read_text()
    assert "## The paper's claims, tested" in text and "read = `r5`" in text
    assert "| refinement >> retrieval (READ N = 100 vs N = 0) | RT +10/-0 (p=0.002)" in text
    # the measured claims drawn beside the report; none measured: no picture
    assert (tmp_path / "report_claims.png").stat().st_size > 0 and "![the claims, pooled](report_claims.png)" in text
    assert not claims.plot_claims(claims.evaluate_claims([], {"read": "r5"}), tmp_path / "none.png")
    assert not (tmp_path / "none.png").exists()
    assert _cli.run(report_cli.main, ["--runs", str(root), "--out", str(out), "--claims", "reader=r5"]) == 2
    assert "unknown role" in capsys.readouterr().err
    assert _cli.run(report_cli.main, ["--runs", str(root), "--out", str(out), "--claims", "read"]) == 2
    assert "ROLE=RUN" in capsys.readouterr().err


def test_training_records_of_the_claimed_runs(tmp_path):
    """Each claimed run's stages: the last step, why it stopped and a link (relative to the report's
    folder) to the loss curve the pipeline committed beside the evaluations; no link where none is."""
    root = tmp_path / "results"
    stop = {"stopped_at": 9500, "reason": "converged", "best_val_loss": 7.7e-4, "best_step": 8000}
    det = {**_result("reach_target", "det_conv", "deterministic", [1, 0]),
           "training": {"deterministic": {"steps": 9500, "stop": stop}}}
    read = {**_result("push_button", "r5", "read", [1, 1]),
            "training": {"vae": {"steps": 3000, "stop": {"reason": "step cap"}}, "read": {"steps": 10, "stop": None}}}
    for r in (det, read):
        r["_file"] = str(root / r["task"] / r["_run_name"] / "eval" / "x.json")
    curve = root / "reach_target" / "det_conv" / "training" / "deterministic" / "loss.png"
    curve.parent.mkdir(parents=True)
    curve.write_bytes(b"png")
    doc = tmp_path / "docs"
    text = "\n".join(claims.training_lines([det, read], {"read": "r5", "deterministic": "det_conv"}, doc))
    assert ("| deterministic | `det_conv` | deterministic | converged | "
            "[RT 9500](../results/reach_target/det_conv/training/deterministic/loss.png) |") in text
    assert "| read | `r5` | vae | step cap | PB 3000 |" in text
    assert "| read | `r5` | read | unfinished | PB 10 |" in text
    assert text.index("| read |") < text.index("| deterministic |")  # in the roles' order
    assert claims.training_lines([det], {"read": "r5"}, doc) == []  # no claimed run trained


def test_read_o_with_each_sampler_is_a_role_of_its_own():
    """Table 6: READ-O trained with EM is a second READ-O run, played by the ``read_o_em`` role; its
    evaluations (method ``read_o``) play no other READ-O role, and CD's run plays no EM one."""
    runs = {"read": "r", "read_o": "cd", "read_o_em": "em"}
    results = [_result("reach_target", "r", "read", [1] * 20),
               _result("reach_target", "cd", "read_o", [1] * 20, n=None),
               _result("reach_target", "em", "read_o", [0] * 12 + [1] * 8, n=None)]
    rows = _by_claim(claims.evaluate_claims(results, runs, (SDE.update, SDE.rounds)))
    table6 = rows["READ-O: EM as good as CD (Table 6)"]
    assert table6["pooled"][:2] == (0, 12) and table6["verdict"].startswith("does not hold")
    assert rows["READ > READ-O with EM"]["pooled"][:2] == (12, 0) and rows["READ > READ-O with EM"]["verdict"] == "holds"
    assert rows["READ > READ-O"]["pooled"][:2] == (0, 0)  # READ-O is CD's run, not EM's
    swapped = _by_claim(claims.evaluate_claims(results, {**runs, "read_o": "em", "read_o_em": "cd"},
                                                (SDE.update, SDE.rounds)))
    assert swapped["READ-O: EM as good as CD (Table 6)"]["verdict"] == "holds"
    assert swapped["READ > READ-O"]["pooled"][:2] == (12, 0)
    unnamed = _by_claim(claims.evaluate_claims(results, {"read": "r", "read_o": "cd"}, (SDE.update, SDE.rounds)))
    assert unnamed["READ > READ-O with EM"]["verdict"] == "not measured"  # no run named for the role
