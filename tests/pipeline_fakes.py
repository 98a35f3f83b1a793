"""Shared by the pipeline tests that plan steps over fake datasets (no episodes, only a summary)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from readjax.lab import pipeline


@pytest.fixture(autouse=True)
def _fingerprint_from_summary(monkeypatch):
    """The fake datasets hold no episodes: a split's content hash is read from its summary.json."""
    def fingerprint(split_dir, episodes):
        f = Path(split_dir) / "summary.json"
        return json.loads(f.read_text())["fingerprint"] if pipeline._summary_kept(split_dir) >= episodes else None

    monkeypatch.setattr(pipeline, "split_fingerprint", fingerprint)
