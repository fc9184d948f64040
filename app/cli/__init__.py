"""The ``paraloop`` command line (:mod:`app.cli.main`).

Run as the ``paraloop`` console script, this package is the first of paraloop to load: a
Ctrl-C from here until :func:`app.cli.main.main` takes over is noted (not a traceback from the
middle of an import) and answered there with exit 130. Before this point only the interpreter's
own start-up runs.
"""

import os
import signal
import sys

#: SIGINTs noted before :func:`app.cli.main.main` installed its handler (console script only)
EARLY_INTERRUPTS: list[int] = []


def note_interrupts() -> None:
    """Note SIGINTs in :data:`EARLY_INTERRUPTS` instead of raising (outside :func:`main`)."""
    signal.signal(signal.SIGINT, lambda signum, frame: EARLY_INTERRUPTS.append(signum))


if os.path.basename(sys.argv[0]) == "paraloop":
    note_interrupts()
