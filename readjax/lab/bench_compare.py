"""A benchmark's timings held against others: a previous run of the same benchmark (``slower_than``:
the regression check of ``--compare``) and the original PyTorch READ timed by the shared harness
(``original_command``, ``run_original``, ``original_ratios``: ``--vs-original``).
"""

from __future__ import annotations

import json
from pathlib import Path


def slower_than(previous: dict, current: dict, factor: float = 2.0) -> list[str]:
    """The cells and parts of ``current`` that take >= ``factor`` x the time they took in ``previous``
    (two planner or two train bench JSONs; cells matched by preset, batch and N, parts by preset and
    batch; every ``*_ms`` figure compared).
    A regression check for a benchmark run, not a unit test: only ratios within one machine mean
    anything."""
    flagged = []

    def index(rows, keys):
        return {tuple(r.get(k) for k in keys): r for r in rows if not r.get("skipped")}

    for section, keys in (("cells", ("preset", "batch", "N")), ("parts", ("preset", "batch"))):
        old = index(previous.get(section, []), keys)
        for key, row in index(current.get(section, []), keys).items():
            if key not in old:
                continue
            for field, value in row.items():
                if not field.endswith("_ms") and field != "ms_per_call":
                    continue
                before = old[key].get(field)
                if before and value >= factor * before:
                    where = " ".join(f"{k}={v}" for k, v in zip(keys, key))
                    flagged.append(f"{where} {field}: {before} -> {value} ({value / before:.1f}x)")
    return flagged


def original_ratios(cells: list[dict], original_plans: list[dict], threads: int) -> list[dict]:
    """Our paper-preset planner cells against the original READ's plan timings (the ``plans`` of
    ``../shared/tools/orig_read_timing.py``) at the same batch, N and thread count: one row per
    cell and original variant (``as_is``, ``cached``), ``speedup`` = original ms / our ms per call."""
    orig = {(p["variant"], p["batch"], p["N"]): p for p in original_plans
            if p.get("measured") and p.get("threads") == threads}
    rows = []
    for c in cells:
        if c.get("skipped") or c.get("preset") != "paper":
            continue
        for variant in ("as_is", "cached"):
            o = orig.get((variant, c["batch"], c["N"]))
            if o:
                rows.append({"batch": c["batch"], "N": c["N"], "variant": variant, "readjax_ms": c["ms_per_call"],
                             "original_ms": o["median_ms"],
                             "speedup": round(o["median_ms"] / c["ms_per_call"], 2)})
    return rows


def original_command(args, out_json: Path) -> list[str]:
    """The shared harness's command line for this benchmark's batches, N, database size, cap on a
    cell's seconds and the original's variants (``as_is``, ``cached``)."""
    return [args.original_python, args.original_harness, args.vs_original, "--threads", str(args.threads),
            "--batches", *map(str, args.batch_sizes), "--steps", *map(str, sorted(args.N)),
            "--variants", *args.original_variants,
            "--repeats", str(args.repeats), "--db-size", str(args.database), "--max-cell-s", str(args.max_seconds),
            "--out", str(out_json)]


def run_original(args, out_json: Path) -> dict:
    """Time the original READ planner with the shared harness, in a subprocess (its own Python with
    torch, see the harness's docstring), at this benchmark's batches, N and database size."""
    import subprocess

    cmd = original_command(args, out_json)
    print("original READ:", " ".join(cmd), flush=True)
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    return json.loads(out_json.read_text())
