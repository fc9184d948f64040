"""What the real-browser tests share: Debian's Chromium via Playwright, its flags, waiting.

Importing this module skips the importing test module when chromium or playwright is missing,
except under ``CI=true`` where that fails (a suite that skips its real parts is a defect).
Never run ``playwright install``: it cannot download browsers here.
"""

from __future__ import annotations

import contextlib
import os
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
import viser

from app import studio as studio_mod
from paraloop_core.design import Design

CHROMIUM = os.environ.get("CHROMIUM", "/usr/bin/chromium")
_CI = os.environ.get("CI", "").lower() == "true"
try:
    from playwright import sync_api as playwright_sync
except ImportError:  # pragma: no cover - depends on the machine
    if _CI:
        raise
    pytest.skip("playwright is not installed", allow_module_level=True)
if not Path(CHROMIUM).exists():
    if _CI:
        raise RuntimeError(f"{CHROMIUM} missing under CI=true (apt-get install chromium)")
    pytest.skip(f"{CHROMIUM} not installed (apt-get install -y chromium)",
                allow_module_level=True)

CHROMIUM_ARGS = [
    "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
    "--disable-background-networking", "--disable-component-update", "--disable-sync",
]

__all__ = ["CHROMIUM", "CHROMIUM_ARGS", "playwright_sync", "serve", "wait_for"]


def wait_for(pred, timeout: float = 10.0, dt: float = 0.05) -> bool:
    """Poll ``pred`` until true or ``timeout`` seconds; its last value."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if pred():
            return True
        time.sleep(dt)
    return pred()


@contextlib.contextmanager
def serve(design: Design, autosave: Path | None = None) -> Iterator[studio_mod.Studio]:
    """A studio on ``design`` served on a free port of 127.0.0.1, settled; stopped after."""
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    studio = studio_mod.Studio(server, design, autosave)
    try:
        assert studio.worker.wait_idle(60)
        yield studio
    finally:
        studio.close()
        server.stop()
