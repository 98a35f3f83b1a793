"""The steps of a grid or a sweep on Ray: each step one Ray task, on whichever node has what it asks.

:func:`run_on_ray` starts an embedded Ray on this machine (no address: as many steps at once as its
CPUs allow) or joins a cluster (``address``, or the ``RAY_ADDRESS`` variable). It submits the steps not
yet done in the grid's order (a task's data, its trainings, their evaluations, then the next task), each
once the steps it ``needs`` have finished and a CPU of the cluster is free, as a Ray task declaring what
it asks of a node (a CPU each, a share of a GPU for a training where the cluster has GPUs, memory:
:mod:`readjax.lab.ray_resources`). So the cores finish one task before they spread over the next, where
Ray left alone would interleave every task's ready steps (its queues are per kind of request) and a
stopped grid would hold half-made tasks. A task runs :func:`readjax.lab.steps.run_step` on its node:
skipped if done by then, else its command, its output checked, its time recorded beside the results.
What makes a step done stays on disk, so every node must see the grid's folders at the same paths (a
shared folder: NFS, a mounted bucket; docs/cluster.md). A step whose worker or node is lost is retried by
Ray (:data:`MAX_RETRIES`), on another node where one is left: the command dies with its worker, and a
retry resumes what it left (or finds it done), so a lost node loses at most its steps in progress. A
failed step fails the steps that need it, not the others: the grid runs on and names every failure at
the end. With a ``deadline`` (a job's wall-clock limit), a step is not started where it and the steps
that need it would end after the deadline (:mod:`readjax.lab.deadline`), nor are those steps.
"""

from __future__ import annotations

import logging
import os
import signal
import sys
import threading
import time
from typing import Callable

from readjax.lab.deadline import DeadlineError, check_start, latest_starts, stamp
from readjax.lab.ray_resources import check_fits, step_resources
from readjax.lab.steps import PipelineError, Step, run_step, step_log_path
from readjax.lab.timing import eta, hms

MAX_RETRIES = 3  # tries of a step after its first whose worker or node was lost


def connect(address: str | None = None):
    """Ray, joined to the cluster at ``address`` (else ``RAY_ADDRESS``; else a new embedded Ray on this
    machine); and whether this call connected it (False: it already was)."""
    import ray

    if ray.is_initialized():
        return ray, False
    address = address or os.environ.get("RAY_ADDRESS") or "local"
    kwargs = {"include_dashboard": False} if address == "local" else {}
    handler = signal.getsignal(signal.SIGTERM)
    ray.init(address=address, logging_level=logging.WARNING, **kwargs)
    if callable(handler) and threading.current_thread() is threading.main_thread():
        # ray.init installs its own, which ends the process at once: keep the caller's (the CLI's `kill` as Ctrl-C,
        # which stops the steps under way and records their time so far)
        signal.signal(signal.SIGTERM, handler)
    return ray, True


def _in_dependency_order(steps: list[Step]) -> list[int]:
    """Indices of ``steps``, each after the steps of the list it needs (their listed order otherwise)."""
    index = {id(s): i for i, s in enumerate(steps)}
    order, placed, visiting = [], set(), set()

    def visit(i: int) -> None:
        if i in placed:
            return
        if i in visiting:
            raise PipelineError(f"`{steps[i].label}` needs itself through the steps it needs")
        visiting.add(i)
        for n in steps[i].needs:
            if id(n) in index:
                visit(index[id(n)])
        visiting.discard(i)
        placed.add(i)
        order.append(i)

    for i in range(len(steps)):
        visit(i)
    return order


def _step_task(steps: list[Step], i: int, cwd: str, python: str, log_path, heartbeat: float) -> dict:
    """One step as a Ray task, on whichever node runs it (submitted once the steps it needs have finished).
    The grid's relative paths are read from ``cwd``, which every node must see; its ``python`` commands
    run with this node's Python."""
    import ray

    step = steps[i]
    node, ip = ray.get_runtime_context().get_node_id(), ray.util.get_node_ip_address()
    if not os.path.isdir(cwd):
        raise PipelineError(f"{step.task}: `{step.label}`: the grid's folder {cwd} is not on node {ip}: every node "
                            f"must see the grid's folders at the same paths (docs/cluster.md)")
    os.chdir(cwd)
    step.argv = [sys.executable if a == python else a for a in step.argv[:1]] + step.argv[1:]
    # a step that asked for no GPU uses none (Ray leaves a GPU node's devices visible to it); steps
    # sharing a GPU must not each claim most of its memory
    env = {"XLA_PYTHON_CLIENT_PREALLOCATE": "false"} if ray.get_gpu_ids() else {"CUDA_VISIBLE_DEVICES": ""}
    if log_path is not None:
        log_path.parent.mkdir(parents=True, exist_ok=True)
        with open(log_path, "a") as f:  # a retry's run follows the lost one's in the same log
            f.write(f"=== {time.strftime('%Y-%m-%dT%H:%M:%S%z')} node {ip} {node}, pid {os.getpid()}\n")
    outcome = run_step(step, log_path=log_path, heartbeat=heartbeat, env=env)
    return {**outcome, "node": node, "ip": ip}


_REMOTE = None


def _remote():
    global _REMOTE
    if _REMOTE is None:
        import ray
        _REMOTE = ray.remote(_step_task)
    return _REMOTE


def run_on_ray(steps: list[Step], log: Callable[[str], None] = print, prior: dict | None = None,
               address: str | None = None, log_dir=None, heartbeat: float = 600.0, resources: dict | None = None,
               on_finished: Callable[[Step], None] | None = None, deadline: float | None = None) -> dict:
    """Run the steps not yet done on Ray (see the module); each step's output goes to
    ``log_dir/<task>/<label>.log`` (a folder every node sees; None: the driver's terminal, through Ray).
    A line per finished step (where it ran, the elapsed time, the ETA priced by ``prior``:
    :func:`readjax.lab.timing.prior_costs`), and every ``heartbeat`` seconds a line with the steps
    under way and how far each has got. ``on_finished(step)`` here after each step that finished.
    ``deadline`` (seconds since the epoch): no step starts that would, with the steps that need it, end
    after it (:func:`readjax.lab.deadline.latest_starts`).
    Returns {"ran", "skipped", "seconds": {kind: s}, "nodes": {(task, label): node id}}; raises
    PipelineError naming every failed step (and those not run for want of one) once the rest is done."""
    todo = [s for s in steps if not s.done()]
    summary = {"ran": 0, "skipped": len(steps) - len(todo), "seconds": {}, "nodes": {}}
    if not todo:
        log(f"pipeline: {len(steps)} steps, all done")
        return summary
    ray, connected = connect(address)
    try:
        return _run(ray, steps, todo, summary, log, prior, log_dir, heartbeat, resources, on_finished, deadline)
    finally:
        if connected:
            ray.shutdown()


def _run(ray, steps, todo, summary, log, prior, log_dir, heartbeat, resources, on_finished, deadline) -> dict:
    cluster, nodes = ray.cluster_resources(), [n for n in ray.nodes() if n.get("Alive")]
    demands = step_resources(resources, cluster.get("GPU", 0.0))
    check_fits(demands, [s.kind for s in todo], nodes)
    slots = max(1, int(cluster.get("CPU", 1)))
    log(f"pipeline: {len(steps)} steps, {summary['skipped']} already done, {len(todo)} to run on Ray: "
        f"{len(nodes)} node(s), {cluster.get('CPU', 0):g} CPUs, {cluster.get('GPU', 0):g} GPUs")
    shared, task = ray.put(todo), _remote()
    index = {id(s): i for i, s in enumerate(todo)}
    needs = {i: [index[id(n)] for n in s.needs if id(n) in index] for i, s in enumerate(todo)}
    starts = latest_starts(todo, needs, deadline, prior, slots)
    waiting, running = _in_dependency_order(todo), {}  # not yet submitted (in order); ref -> index
    finished, failed, failures, late = set(), set(), [], set()
    by_kind: dict[str, list[float]] = {}
    by_label: dict[str, list[float]] = {}
    t_start = time.time()

    def not_run(i: int, lost: list[int]) -> None:
        failed.add(i)
        if set(lost) <= late:
            late.add(i)
            return
        why = f"not run: it needs `{todo[lost[0]].label}`, which failed"
        failures.append(f"{todo[i].task}: `{todo[i].label}` {why}")
        log(f"failed  {todo[i].task}: {todo[i].label} ({why})")

    def submit() -> None:
        """The steps :func:`next_steps` gives, each unless it would end after the deadline (then again, as
        that frees a CPU and fails the steps that need it)."""
        blocked = True
        while blocked:
            blocked = False
            go, unrunnable = next_steps(waiting, needs, finished, failed, slots - len(running))
            for i, lost in unrunnable:
                not_run(i, lost)
            for i in go:
                waiting.remove(i)
                try:
                    check_start(todo[i], *starts[i])
                except DeadlineError as e:
                    if not late:  # the first says why (its price), the rest are counted at the end
                        log(f"deadline: steps that would end after {stamp(deadline)} are not started; the first: {e}")
                    failed.add(i)
                    late.add(i)
                    blocked = True
                    continue
                s = todo[i]
                path = None if log_dir is None else step_log_path(log_dir, s)
                ref = task.options(**demands[s.kind], max_retries=MAX_RETRIES, name=f"{s.task}: {s.label}").remote(
                    shared, i, os.getcwd(), sys.executable, path, heartbeat)
                running[ref] = i

    try:
        submit()
        while running:
            ready, _ = ray.wait(list(running), num_returns=1, timeout=heartbeat)
            if not ready:
                log(_running_line(todo, running.values(), waiting, needs, finished, by_label, by_kind, prior, slots,
                                  t_start))
                continue
            i = running.pop(ready[0])
            step = todo[i]
            try:
                outcome = ray.get(ready[0])
            except Exception as e:  # noqa: BLE001  the step's own error, or how Ray lost it
                failed.add(i)
                why = _reason(e)
                failures.append(why if isinstance(getattr(e, "cause", None), PipelineError)
                                else f"{step.task}: `{step.label}` {why}")
                log(f"failed  {step.task}: {step.label}")
                submit()
                continue
            finished.add(i)
            summary["nodes"][(step.task, step.label)] = outcome["node"]
            if on_finished is not None:
                on_finished(step)
            if not outcome["ran"]:
                summary["skipped"] += 1
                log(f"skipped {step.task}: {step.label} ({outcome['status']})")
            else:
                summary["ran"] += 1
                by_kind.setdefault(step.kind, []).append(outcome["cost"])  # a resumed step: every run of it
                by_label.setdefault(step.label, []).append(outcome["cost"])
                left = eta([todo[j] for j in (*waiting, *running.values())], by_label, by_kind, prior)
                log(f"[{len(finished) + len(failed)}/{len(todo)}] done {step.task}: {step.label} in "
                    f"{hms(outcome['seconds'])} on node {outcome['ip']} {outcome['node'][:8]} (elapsed "
                    f"{hms(time.time() - t_start)}{', ETA ' + hms(left / slots) if left is not None else ''})")
            submit()
    except KeyboardInterrupt:  # Ctrl-C or `kill` (the CLI's SIGTERM): stop the steps under way with the grid
        for ref in running:
            ray.cancel(ref)
        ray.wait(list(running), num_returns=len(running), timeout=60)
        raise
    summary["seconds"] = {k: sum(v) for k, v in by_kind.items()}
    if late:
        failures.append(f"{len(late)} steps not started: they would end after the deadline ({stamp(deadline)}); "
                        f"first `{todo[min(late)].task}: {todo[min(late)].label}`")
        log(f"deadline: {len(late)} steps not started, to run on a re-run")
    if failures:
        raise (DeadlineError if len(failures) == 1 and late else PipelineError)(
            "; ".join(failures) + "\nre-run the same command to go on: finished steps are skipped")
    return summary


def _reason(error: Exception) -> str:
    """A failed task's message: the step's own error (a PipelineError), or how Ray lost it."""
    cause = getattr(error, "cause", None)
    if isinstance(cause, PipelineError):
        return str(cause)
    return f"failed in Ray (a lost worker or node is retried {MAX_RETRIES} times): {type(error).__name__}: {error}"


def next_steps(waiting: list[int], needs: dict[int, list[int]], finished: set[int], failed: set[int],
               free: int) -> tuple[list[int], list[tuple[int, list[int]]]]:
    """(the first ``free`` steps of ``waiting`` whose needs have all finished, in its order; the steps of
    ``waiting`` that need a failed step, each with the failed steps it needs, and any step that needs one
    of those, taken out of ``waiting``). ``waiting`` is in dependency order."""
    go, unrunnable, lost_now = [], [], set()
    for i in list(waiting):
        lost = [n for n in needs[i] if n in failed or n in lost_now]
        if lost:
            waiting.remove(i)
            unrunnable.append((i, lost))
            lost_now.add(i)
        elif len(go) < free and all(n in finished for n in needs[i]):
            go.append(i)
    return go, unrunnable


def _running_line(todo, running, waiting, needs, finished, by_label, by_kind, prior, slots: int, t_start: float) -> str:
    """The periodic line: the steps under way, with how far each has got (a training: its stages' steps),
    how many are ready for a free CPU and how many wait for other steps, and the ETA of the rest."""
    parts = []
    for i in running:
        step, how_far = todo[i], ""
        if step.progress is not None:
            try:
                how_far = f" ({step.progress() or 'starting'})"
            except (OSError, ValueError, KeyError):  # a record half-written: the next line will have it
                pass
        parts.append(f"{step.task}: {step.label}{how_far}")
    ready = sum(all(n in finished for n in needs[i]) for i in waiting)
    left = eta([todo[i] for i in (*running, *waiting)], by_label, by_kind, prior)
    return (f"under way  {'; '.join(parts)}  (elapsed {hms(time.time() - t_start)}, {ready} ready for a free CPU, "
            f"{len(waiting) - ready} waiting for other steps{', ETA ' + hms(left / slots) if left is not None else ''})")
