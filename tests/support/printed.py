"""What ``--json`` prints of a result: the CLI writes ``json.dumps`` of a dictionary."""

from __future__ import annotations

import json
from typing import Any


def as_printed(doc: Any) -> Any:
    """``doc`` as ``odocal ... --json`` prints it and ``json.loads`` reads it back (tuples become
    lists, keys strings)."""
    return json.loads(json.dumps(doc, allow_nan=False))
