"""The core's texts (errors, export warnings) in the studio's words: the command line's
options named in them become the controls the studio has, so no GUI text names a flag."""

from __future__ import annotations

import re

#: (the core's phrase, the studio's) - the phrases of ``paraloop_core.fabrication``'s notes.
PHRASES = (
    ("print the parts separately with --joints m3 (screws) or printed-pin",
     "switch off Print in place: the parts then print separately, joined by screws"),
)
#: Options left over, by name: the studio's control for it.
OPTIONS = {"size-mm": "Size (mm)", "ground-link": "Column on link",
           "print-in-place": "Print in place", "no-ground": "Grounding column off",
           "carve-radius": "Space radius (mm)", "resolution": "Voxels per space"}
_OPTION = re.compile(r"`?--([a-z][a-z0-9-]*)`?")


def gui_text(text: str) -> str:
    """``text`` with every command-line option replaced by the studio's words: the known
    phrases first (:data:`PHRASES`), then any option by its control (:data:`OPTIONS`) or, if
    the studio has none, its name in words."""
    for old, new in PHRASES:
        text = text.replace(old, new)
    return _OPTION.sub(lambda m: OPTIONS.get(m.group(1), m.group(1).replace("-", " ")), text)
