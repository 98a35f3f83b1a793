"""Ground-truth replay records, one per version of a split: ``results/<task>/verify/<split>_<fingerprint>.json``.

An evaluation measures what it says only on a split whose own expert motions replay at 100 % through
the evaluation path (``experiments.verify``). A split generated on two machines is the same scenes
with motions that differ in float rounding, so its content hash (``Dataset.fingerprint``) differs
too. Each version therefore keeps its own record, and an evaluation is matched to the record of the
split it ran on (its ``test_fingerprint``): the pipeline skips a verification only when the split on
this machine has one, and the report marks a number whose split has none.
"""

from __future__ import annotations

import json
from pathlib import Path

FOLDER = "verify"


def record_path(results: str | Path, task: str, fingerprint: str, split: str = "test") -> Path:
    """Where the replay record of ``task``'s ``split`` with content hash ``fingerprint`` lives."""
    return Path(results) / task / FOLDER / f"{split}_{fingerprint}.json"


def write(results: str | Path, record: dict) -> Path:
    """Store a replay record (``evaluation.replay_ground_truth``'s result) under its split's
    fingerprint; returns the path."""
    for key in ("task", "split", "dataset_fingerprint"):
        if not record.get(key):
            raise ValueError(f"a replay record needs {key!r}; got keys {sorted(record)}")
    path = record_path(results, record["task"], record["dataset_fingerprint"], record["split"])
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(record, indent=2))
    return path


def passed(record: dict | None, episodes: int) -> bool:
    """Whether a record replays at least ``episodes`` episodes, every one of them successfully."""
    return bool(record) and record.get("episodes", 0) >= episodes and record.get("success_rate") == 1.0


def find(results: str | Path, task: str, fingerprint: str | None, split: str = "test") -> dict | None:
    """The replay record of that split version, or None (no record, or an unreadable one)."""
    if not fingerprint:
        return None
    path = record_path(results, task, fingerprint, split)
    try:
        return json.loads(path.read_text())
    except (FileNotFoundError, json.JSONDecodeError):
        return None


def is_verified(results: str | Path, task: str, fingerprint: str | None, episodes: int, split: str = "test") -> bool:
    """Whether ``task``'s ``split`` with content hash ``fingerprint`` replayed its first
    ``episodes`` (or more) at 100 %, by the records under ``results``."""
    return passed(find(results, task, fingerprint, split), episodes)


def evaluation_verified(results: str | Path, r: dict) -> bool:
    """Whether the split an evaluation result ran on (its ``split``: test, or val; records older than
    the field ran on the test split) has a 100 % replay of at least as many episodes on record."""
    return is_verified(results, r["task"], r.get("test_fingerprint"), r.get("episodes", len(r.get("success", []))),
                       split=r.get("split", "test"))
