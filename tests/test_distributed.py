"""One training across processes (``experiments.train --distributed``, :mod:`readjax.distributed`):
two local processes on the CPU (one device each, jax.distributed with gloo, coordinator 127.0.0.1,
inside a private network namespace where only the loopback exists) train the tiny READ run of
``tests.multiprocess``; their parameters equal a one-process training with the same global batch,
the records are written once, and a training whose processes are all killed mid-run resumes to the
same parameters. Plus the pieces: a process's part of a batch, its rows, the CLI's checks."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys

import numpy as np
import pytest

from experiments import _cli
from experiments import train as train_cli
from readjax import sharding
from readjax.methods import base
from readjax.training import StageSpec
from tests import multiprocess

pytestmark = pytest.mark.timeout(900)


def _namespace_available() -> bool:
    if shutil.which("unshare") is None or shutil.which("ip") is None:
        return False
    return subprocess.run(["unshare", "-n", "ip", "link", "set", "lo", "up"], capture_output=True).returncode == 0


needs_namespace = pytest.mark.skipif(not _namespace_available(),
                                     reason="needs `unshare -n` (root) to keep the processes on a private loopback")


def _in_namespace(data, out, *extra) -> dict:
    """``tests.multiprocess`` inside a fresh private network namespace; returns its record."""
    cmd = ["unshare", "-n", sys.executable, "-m", "tests.multiprocess", "--data", str(data), "--out", str(out), *extra]
    done = subprocess.run(cmd, cwd=multiprocess.ROOT, env=multiprocess.environment(1), capture_output=True, text=True,
                          timeout=800)
    logs = "\n".join(f"--- {f.name}\n{f.read_text()[-3000:]}" for f in sorted((out / "logs").glob("*.log"))) \
        if (out / "logs").is_dir() else ""
    assert done.returncode == 0, f"{done.stdout[-2000:]}\n{done.stderr[-3000:]}\n{logs}"
    record = json.loads(done.stdout.strip().splitlines()[-1])
    print(f"two processes, {len(record)} facts: {record}")  # seen with -s: the kill time, each attempt's wall
    return record


RUN = ("reach_target", "read")


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """The tiny training twice: one process on this pytest process's 2 host devices (the same global
    mesh shape and batch: the reference), and two processes of one device each, both SIGKILLed once
    the autoencoder's step-2 checkpoint exists, then started again with the same command."""
    import jax

    root = tmp_path_factory.mktemp("distributed")
    data = multiprocess.write_split(root / "data")
    before = jax.config.jax_persistent_cache_min_compile_time_secs
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)  # the processes reuse its compiles
    try:
        assert _cli.run(train_cli.main, multiprocess.train_argv(data, root / "one")) == 0
    finally:
        jax.config.update("jax_persistent_cache_min_compile_time_secs", before)
    out = root / "two"
    record = _in_namespace(data, out, "--kill-at", str(out / RUN[0] / RUN[1] / "vae" / "checkpoints" / "2"))
    return root / "one" / RUN[0] / RUN[1], out / RUN[0] / RUN[1], record


@needs_namespace
def test_two_processes_train_the_one_process_model_and_write_its_records_once(runs):
    """The autoencoder's first 2 steps (before the kill) and the whole denoiser stage (after the
    restart) were each trained by the two processes without a break: their states equal the
    one-process training's, and so do the validation losses and the convergence rule's decisions;
    every record is written once, by process 0."""
    one, two, _ = runs
    for stage, step in (("vae", 2), ("read", 4)):
        a, b = multiprocess.checkpoint(one / stage, step), multiprocess.checkpoint(two / stage, step)
        assert int(a["step"]) == int(b["step"]) == step
        difference = multiprocess.max_abs_difference(a["params"], b["params"])
        print(f"{stage} after {step} steps, two processes vs one: max |params difference| = {difference:.3g}")
        assert difference <= 1e-6
        assert multiprocess.max_abs_difference(a["opt_state"], b["opt_state"]) <= 1e-6
    for stage in ("vae", "read"):
        rows_one = [json.loads(ln) for ln in (one / stage / "metrics.jsonl").read_text().splitlines()]
        rows_two = [json.loads(ln) for ln in (two / stage / "metrics.jsonl").read_text().splitlines()]
        assert [r["step"] for r in rows_two] == [2, 4]  # one line per logged step, not one per process
        for key in ("loss", "val_loss"):
            np.testing.assert_allclose([r[key] for r in rows_two], [r[key] for r in rows_one], rtol=1e-5)
        stop = json.loads((two / stage / "stop.json").read_text())
        assert stop["reason"] == "converged" and stop["stopped_at"] == 4
        assert (two / stage / "loss.png").is_file() and (two / stage / "stage.json").is_file()
        assert sorted(int(p.name) for p in (two / stage / "checkpoints").iterdir()) == [2, 4]
    assert json.loads((two / "run.json").read_text())["dataset_fingerprint"] == \
        json.loads((one / "run.json").read_text())["dataset_fingerprint"]
    logs = two.parent.parent / "logs"
    assert '"read_steps": 4' in (logs / "attempt1_process0.log").read_text()  # the primary reports
    process1 = (logs / "attempt1_process1.log").read_text()
    assert "process 1 of 2: 1 of 2 devices" in process1 and "read_steps" not in process1


@needs_namespace
def test_a_two_process_training_killed_mid_run_resumes_to_the_uninterrupted_parameters(runs):
    """Both processes were killed once the autoencoder's step-2 checkpoint existed (the denoiser
    stage not trained yet); the same command resumed the training from its checkpoints: the final states of both stages are the uninterrupted
    training's, no logged step lost or repeated."""
    one, two, record = runs
    assert record["killed"] and record["attempt1_rc"] == [0, 0]
    assert all("/vae/" in f for f in record["finished_at_kill"])  # the denoiser stage had not finished
    for stage in ("vae", "read"):
        a, b = multiprocess.checkpoint(one / stage), multiprocess.checkpoint(two / stage)
        assert int(a["step"]) == int(b["step"]) == 4
        difference = multiprocess.max_abs_difference(a, b)
        print(f"{stage} final state, killed and resumed vs uninterrupted: max |difference| = {difference:.3g}")
        assert difference <= 1e-6
    steps = [json.loads(ln)["step"] for ln in (two / "vae" / "metrics.jsonl").read_text().splitlines()]
    assert steps == [2, 4]


class _Data:
    def __init__(self, n):
        rng = np.random.default_rng(0)
        self.rgbd = rng.uniform(size=(n, 4, 4, 4)).astype(np.float32)
        self.motion = rng.normal(size=(n, 101, 10)).astype(np.float32)

    def __len__(self):
        return len(self.motion)


def test_a_part_of_a_batch_is_those_rows_of_the_whole():
    """What each process builds (``Batches.rows``): the same demos, neighbours and per-sample extras
    as the rows of the batch one process would build; in one process its rows are all of them."""
    ds = _Data(20)
    pairs = np.stack([(np.arange(20) + s) % 20 for s in (1, 2, 3)], axis=1)
    spec = StageSpec(steps=10, batch_size=6, seed=3)
    for codes in (None, np.arange(20, dtype=np.float32)[:, None] * np.ones((1, 4), np.float32)):
        batches = base.paired_batch(ds, spec, pairs, 20, codes=codes, norm=np.arange(6.0)[:, None])
        whole = batches(5)
        for rows in (slice(0, 3), slice(3, 6), slice(2, 5)):
            part = batches.rows(5, rows)
            assert part.keys() == whole.keys()
            for k in whole:
                np.testing.assert_array_equal(part[k], whole[k][rows])
    assert sharding.process_rows(8) == slice(0, 8)


def test_importing_readjax_leaves_the_backend_unstarted():
    """jax.distributed.initialize must come before JAX's backend starts: importing readjax (its
    runtime set-up, the CLI plumbing, the training code) must not start it."""
    code = ("import readjax, experiments._cli, experiments.train, readjax.training, readjax.methods.read; "
            "from jax._src import xla_bridge as xb; print(xb.backends_are_initialized())")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         cwd=multiprocess.ROOT, env=multiprocess.environment(1))
    assert out.stdout.strip().splitlines()[-1] == "False", out.stderr[-2000:]


def test_the_cli_refuses_process_options_without_distributed_and_a_bad_process_id(monkeypatch, capsys):
    assert _cli.run(train_cli.main, ["--task", "RT", "--process-id", "1"]) == 2
    assert "go with --distributed" in capsys.readouterr().err
    from readjax import distributed

    monkeypatch.setenv("JAX_NUM_PROCESSES", "2")
    monkeypatch.setenv("JAX_PROCESS_ID", "2")
    with pytest.raises(ValueError, match="not one of the 2 processes"):
        distributed.initialize("127.0.0.1:1")
    monkeypatch.setenv("JAX_PROCESS_ID", "one")
    with pytest.raises(ValueError, match="not an integer"):
        distributed.initialize("127.0.0.1:1")
