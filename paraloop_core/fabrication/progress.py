"""The progress callback of the long fabrication steps: ``progress(share, words)``, the share
done in ``[0, 1]`` and what is being done, in words (the studio shows both)."""

from __future__ import annotations

from collections.abc import Callable

Progress = Callable[[float, str], None]
