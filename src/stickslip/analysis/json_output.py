"""JSON files of the analysis results: non-finite numbers (no such point, diverged) are written as null."""

import json
import math
from pathlib import Path


def _json(obj):
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if isinstance(obj, dict):
        return {k: _json(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_json(v) for v in obj]
    return obj


def write_json(path, obj):
    """Write ``obj`` (dicts, lists, numbers, strings) to ``path`` as indented JSON, non-finite floats as null."""
    Path(path).write_text(json.dumps(_json(obj), indent=2) + "\n")
