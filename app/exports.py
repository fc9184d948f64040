"""What the studio's export button downloads (one function, so more formats can be added)."""

from __future__ import annotations

import json

from paraloop_core import pipeline


def export_files(solution: pipeline.Solution) -> list[tuple[str, bytes]]:
    """Files ``(name, content)`` exported for a solved design: the result JSON."""
    result = json.dumps(pipeline.result_to_dict(solution), indent=1) + "\n"
    return [("paraloop-result.json", result.encode("utf-8"))]
