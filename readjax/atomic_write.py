"""Writing a file whole: a reader (a parallel grid, a resumed run) sees the old content or the new,
never half of it. The text goes to a temporary file beside the target, which is then renamed over it."""

from __future__ import annotations

import os
from pathlib import Path


def write_text(path: str | Path, text: str, tmp_name: str | None = None) -> None:
    """Replace ``path``'s content with ``text`` atomically. ``tmp_name``: the temporary file's name in
    the same folder (default ``<name>.tmp``; a writer that may race another names its own)."""
    path = Path(path)
    tmp = path.with_name(tmp_name or path.name + ".tmp")
    tmp.write_text(text)
    os.replace(tmp, path)
