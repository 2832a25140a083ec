"""journal.jsonl: one line per finished mission (its fingerprint and row), so that a rerun resumes."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import IO


def read_journal(path: Path) -> dict[str, tuple[str, dict]]:
    """Mission id -> (fingerprint, row) of every complete line of the journal at ``path`` (none if absent)."""
    found: dict[str, tuple[str, dict]] = {}
    if not path.is_file():
        return found
    for line in path.read_text(encoding="utf-8").splitlines():
        try:
            rec = json.loads(line)
            found[rec["row"]["mission_id"]] = (rec["fingerprint"], rec["row"])
        except (ValueError, KeyError, TypeError):
            continue  # a line cut short by a killed run
    return found


def append_row(journal: IO[str], fingerprint: str, row: dict) -> None:
    """Append a finished mission's line and flush it to disk (a killed run loses no finished mission)."""
    journal.write(json.dumps({"fingerprint": fingerprint, "row": row}) + "\n")
    journal.flush()
    os.fsync(journal.fileno())
