"""The ``paraloop`` command line: ``solve``, ``validate ...``, ``export``, ``animate``,
``simulate``, ``studio``.

Every failure caused by the input prints one line ``error: <file>: <field>: <reason>`` on stderr;
output paths are checked before any work starts, nothing is overwritten without ``--force`` and
no partial or temporary file is left behind. Exit codes (``docs/result-format.md``): 0 done,
3 solved but not realized, 2 input refused, 1 internal error (``--debug`` shows the traceback),
130 interrupted (Ctrl-C at any moment, one line).

Start-up: this module imports the standard library and :mod:`app.cli.outputs` only; a
sub-command's module (and with it numpy, the studio's viser, the fabrication's trimesh) is
imported when that command runs or shows its ``--help``, so ``paraloop solve`` never loads
the studio or the mesh libraries.
"""

from __future__ import annotations

import argparse
import importlib
import signal
import sys
from types import ModuleType
from typing import NoReturn

from app import cli
from app.cli import outputs
from app.cli.outputs import EXIT_INTERRUPTED, EXIT_REFUSED

#: sub-command -> (module whose ``register`` adds it, help in the command list), in the order
#: of ``paraloop --help``; ``validate`` is a group of :data:`VALIDATIONS`
COMMANDS: dict[str, tuple[str, str]] = {
    "solve": ("app.cli.solve", "solve design files and write result JSON"),
    "validate": ("", "statistical validations of the paper"),
    "studio": ("app.studio", "open the design studio in the browser"),
    "export": ("app.cli.export", "export printable, verified parts of a design"),
    "animate": ("app.cli.animate", "write the realized loop as an animated glTF"),
    "simulate": ("app.cli.simulate", "MuJoCo physics check of the printed parts"),
}
VALIDATIONS: dict[str, tuple[str, str]] = {
    "realization": ("app.cli.validate_realization",
                    "Table 1: realize AS and DB loops of random cubic motions"),
    "evolution": ("app.cli.validate_evolution",
                  "Fig. 16: evolution from many random starts on sampled targets"),
}


class Parser(argparse.ArgumentParser):
    """Usage errors on one line (``error: ...``), exit status 2."""

    def error(self, message: str) -> None:  # type: ignore[override]
        print(f"error: {self.prog}: {outputs.one_line(message)} (see {self.prog} --help)",
              file=sys.stderr)
        raise SystemExit(EXIT_REFUSED)


def _add_debug(parser: argparse.ArgumentParser, top: bool = True) -> None:
    """``--debug`` accepted before or after the sub-command (tracebacks of internal errors)."""
    parser.add_argument("--debug", action="store_true",
                        default=False if top else argparse.SUPPRESS,
                        help="print the traceback of an internal error")
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for child in action.choices.values():
                _add_debug(child, top=False)


def _words(argv: list[str] | None) -> list[str]:
    """The sub-command words of ``argv`` (its leading non-option arguments), e.g.
    ``["validate", "realization"]``; None (build every command) gives ``["*", "*"]``."""
    if argv is None:
        return ["*", "*"]
    return [a for a in argv if not a.startswith("-")][:2] + ["", ""]


def _register(subparsers: argparse._SubParsersAction, table: dict[str, tuple[str, str]],
              chosen: str, nested: str) -> None:
    """Add ``table``'s commands: the ``chosen`` one (every one for ``*``) in full from its
    module, the others as names with their help (no import)."""
    for name, (module, help_) in table.items():
        if name == "validate":
            validate = subparsers.add_parser(name, help=help_)
            group = validate.add_subparsers(dest="what", required=True)
            _register(group, VALIDATIONS, nested if chosen in (name, "*") else "", "")
        elif chosen in (name, "*"):
            _module(module).register(subparsers)
        else:
            subparsers.add_parser(name, help=help_, add_help=False)


def _module(name: str) -> ModuleType:
    return importlib.import_module(name)


def build_parser(argv: list[str] | None = None) -> argparse.ArgumentParser:
    """The parser of ``argv``: the sub-command it names is built from its module, the others
    are names only (``argv`` None: all of them in full)."""
    parser = Parser(prog="paraloop", description="Design invertible paradoxical 6R loops.")
    sub = parser.add_subparsers(dest="command", required=True)
    command, nested = _words(argv)[:2]
    _register(sub, COMMANDS, command, nested)
    _add_debug(parser)
    return parser


def _run(argv: list[str]) -> int:
    try:
        args = build_parser(argv).parse_args(argv)
        if not hasattr(args, "func"):  # a placeholder was chosen (odd argv): build them all
            args = build_parser(None).parse_args(argv)
    except SystemExit as exc:  # --help (0) or a usage error (2, already printed)
        return exc.code if isinstance(exc.code, int) else EXIT_REFUSED
    debug = bool(getattr(args, "debug", False))
    try:
        return int(args.func(args) or 0)
    except (ValueError, OSError) as exc:  # bad input or unusable output: one line
        outputs.check_interrupt()
        print(f"error: {outputs.one_line(exc)}", file=sys.stderr)
        return EXIT_REFUSED
    except Exception as exc:
        return outputs.internal_error("", exc, debug)


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit code (never raises, never prints a traceback
    unless ``--debug``; Ctrl-C at any moment: one line, 130)."""
    argv = sys.argv[1:] if argv is None else list(argv)
    outputs.catch_interrupts()
    try:
        try:
            if cli.EARLY_INTERRUPTS:  # pressed while this module was loading
                raise KeyboardInterrupt
            return _run(argv)
        except Exception as exc:  # e.g. a sub-command's module failing to import
            return outputs.internal_error("", exc, "--debug" in argv)
    except KeyboardInterrupt as exc:  # also raised by the handlers above after a Ctrl-C
        outputs.seen(exc)
        print("error: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    finally:
        outputs.restore_interrupts()


def console() -> NoReturn:
    """The ``paraloop`` script: :func:`main`, then Ctrl-C ignored. The outcome is decided and
    written by then; a press while the interpreter shuts down would otherwise end it by the
    default action (exit -2, no message) after a complete run. Outside :func:`main` a press
    is only noted (:func:`app.cli.note_interrupts`), never a traceback."""
    cli.note_interrupts()
    code = main()
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    sys.exit(code)


if __name__ == "__main__":
    console()
