"""The refinement issue's checks on a refine_report (no model needed): the verdicts, the per-image
counts and the sign test, and the CLI's --summary over saved reports."""

import json

import numpy as np
import pytest

from experiments import refine_report as cli
from readjax.lab import paired, refine_report


def _row(split, n, errs):
    errs = np.asarray(errs, float)
    return {"split": split, "N": n, "err_cm_median": float(np.median(errs)), "err_cm": errs.tolist()}


def _report(task="reach_target", train_1=(0.5, 0.6, 0.7), train_100=(0.5, 0.8, 0.9), test_0=(4.0, 5.0, 6.0),
            test_100=(1.0, 1.0, 7.0)):
    return {"task": task, "run": f"runs/{task}/read", "rows": [
        _row("train", 0, [0, 0, 0]), _row("train", 1, train_1), _row("train", 100, train_100),
        _row("test", 0, test_0), _row("test", 1, test_0), _row("test", 100, test_100)]}


def test_sign_test_matches_the_binomial_and_mcnemar():
    assert paired.sign_test_p(0, 0) == 1.0
    assert paired.sign_test_p(5, 0) == pytest.approx(2 / 32)
    assert paired.sign_test_p(3, 7) == paired.sign_test_p(7, 3) == pytest.approx(2 * (1 + 10 + 45 + 120) / 1024)
    a = np.array([1, 1, 1, 0, 0, 1], bool)
    b = np.array([0, 0, 1, 1, 0, 1], bool)  # discordant: a only 2, b only 1
    assert paired.mcnemar_p(a, b) == paired.sign_test_p(2, 1) == 1.0
    with pytest.raises(ValueError):
        paired.sign_test_p(-1, 2)


def test_checks_compare_the_largest_n_with_n1_on_training_and_n0_on_test_images():
    train, test = refine_report.checks(_report())
    assert (train["split"], train["N"], train["against"]) == ("train", 100, 1)
    assert not train["holds"] and train["margin_mm"] == pytest.approx(2.0)  # median 0.8 against 0.6 cm
    assert (train["worse"], train["better"], train["ties"]) == (2, 0, 1)  # 0.5 -> 0.5 is a tie
    assert train["median_diff_mm"] == pytest.approx(2.0)
    assert (test["split"], test["against"]) == ("test", 0)
    assert test["holds"] and test["margin_mm"] == pytest.approx(-40.0)
    assert (test["worse"], test["better"]) == (1, 2) and test["sign_p"] == 1.0


def test_a_difference_within_the_tie_counts_as_neither_side():
    r = _report(train_1=(0.5, 0.5, 0.5), train_100=(0.5 + refine_report.TIE_CM / 2,) * 3)
    train = refine_report.checks(r)[0]
    assert (train["worse"], train["better"], train["ties"]) == (0, 0, 3) and train["sign_p"] == 1.0
    assert not train["holds"]  # the median verdict is strict, as the issue states it


def test_reports_without_per_image_errors_keep_the_median_verdict():
    r = _report()
    for row in r["rows"]:
        del row["err_cm"]
    train, test = refine_report.checks(r)
    assert not train["holds"] and test["holds"] and train["worse"] is None
    assert "per image" not in refine_report.format_check(train)
    assert "| – |" in refine_report.format_checks_table([r])


def test_checks_need_the_n_they_compare():
    r = _report()
    r["rows"] = [row for row in r["rows"] if row["N"] != 1]
    assert [c["split"] for c in refine_report.checks(r)] == ["test"]
    assert refine_report.checks({"rows": []}) == []


def test_summary_tabulates_saved_reports_and_refuses_other_json(tmp_path, capsys):
    paths = []
    for task in ("reach_target", "push_button"):
        p = tmp_path / f"{task}.json"
        p.write_text(json.dumps(_report(task)))
        paths.append(str(p))
    cli.main(["--summary", *paths])
    out = capsys.readouterr().out.splitlines()
    assert len(out) == 4 and out[2].startswith("| reach_target | read |") and "no (+2.00 mm)" in out[2]
    bad = tmp_path / "ranks.json"
    bad.write_text(json.dumps({"reports": []}))
    with pytest.raises(ValueError, match="not a refine_report JSON"):
        cli.main(["--summary", str(bad)])
    with pytest.raises(ValueError, match="either --run"):
        cli.main(["--run", "x", "--summary", paths[0]])
    with pytest.raises(FileNotFoundError):
        cli.main(["--summary", str(tmp_path / "missing.json")])


def test_the_report_gathers_saved_refine_reports_by_run_name(tmp_path):
    from readjax.lab import report

    def save(run, name, record):
        f = tmp_path / "reach_target" / run / "diagnostics" / name
        f.parent.mkdir(parents=True, exist_ok=True)
        f.write_text(json.dumps(record))

    save("read", "refine_cold_anchor_rounds2.json", _report())
    save("read", "correction_range_cold_anchor_ranks1-500.json", {"task": "reach_target", "reports": []})
    save("other", "refine_cold.json", _report())
    found = report.refine_reports(tmp_path, include=("read",))
    assert [r["label"] for r in found] == ["read: cold_anchor_rounds2"]
    lines = "\n".join(report.refine_check_lines(found)).splitlines()
    assert lines[0].startswith("## Refinement against the ground truth")
    assert any(line.startswith("| reach_target | read: cold_anchor_rounds2 | 0.600 -> 0.800") for line in lines)
    assert report.refine_check_lines([]) == []
    assert len(report.refine_reports(tmp_path, exclude=("read",))) == 1
