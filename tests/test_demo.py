"""`make demo` (experiments.demo), end to end at a tiny size: every stage runs, the table has its
three rows and the replayed expert motions read 100 %; a bad override fails before any work."""

from __future__ import annotations

import pytest

from experiments import _cli
from experiments import demo

pytestmark = pytest.mark.timeout(1500)

TINY = ["vae_batch=4", "batch=4", "log_every=1", "denoiser.enc_depths=0,1,0,1", "denoiser.dec_depths=0,0,1",
        "denoiser.layers=1"]


def test_a_bad_override_fails_before_anything_is_generated(tmp_path, capsys):
    out = tmp_path / "demo"
    assert _cli.run(demo.main, ["--out", str(out), "--set", "no_such_field=1"]) == 2
    assert "no_such_field" in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.slow  # in the full default run, a later XLA compile segfaulted after it (see BENCHMARKS 8e)
def test_the_demo_runs_end_to_end_and_its_ground_truth_replays(tmp_path, capsys):
    out = tmp_path / "demo"
    argv = ["--out", str(out), "--episodes", "8", "--test-episodes", "2", "--vae-steps", "2", "--steps", "2",
            "--N", "1"] + sum((["--set", s] for s in TINY), [])
    assert _cli.run(demo.main, argv) == 0
    text = capsys.readouterr().out
    table = text[text.index("method"):]
    rows = {line.rsplit(None, 2)[0].strip(): line.split()[-2:] for line in table.splitlines()[2:5]}
    assert set(rows) == {"READ (N=1)", "retrieval only (N=0)", "expert motions replayed (must be 100)"}
    assert rows["expert motions replayed (must be 100)"] == ["100.0", "100.0"]
    for name in ("READ (N=1)", "retrieval only (N=0)"):
        assert 0.0 <= float(rows[name][0]) <= 100.0
    run = out / "runs" / "reach_target" / "read"
    assert (run / "eval" / "demo_N1.json").exists() and (run / "eval" / "demo_N0.json").exists()
    assert (run / "eval" / "demo_N1_overlay.png").exists()
    assert (out / "first_frames.png").exists()
