"""Exceptions with a machine-readable ``reason``; all are ``ValueError`` (bad or degenerate
input). Messages quote input values in JSON spelling (:func:`shown`)."""

from __future__ import annotations

import json
import numbers
from typing import Any

#: longest string and most list / object entries quoted by :func:`shown`
_QUOTE_CHARS, _QUOTE_ITEMS = 40, 4
#: largest integer (in bits, ~4000 digits) written out in full: str() refuses longer ones
_INT_BITS = 13_000


def shown(v: Any, depth: int = 2) -> str:
    """``v`` as JSON spells it (``true``, ``null``, ``"text"``, ``[1, 2]``), on one bounded
    ASCII line, for messages that quote input: safe on huge integers, long strings and deep
    values (``NaN`` / ``Infinity`` as Python's json module writes them)."""
    if v is None or isinstance(v, bool):
        return json.dumps(v)
    if isinstance(v, numbers.Integral):
        v = int(v)
        if v.bit_length() > _INT_BITS:
            return f"<an integer of about {int(v.bit_length() * 0.30103) + 1} digits>"
        text = str(v)
        return text if len(text) <= _QUOTE_CHARS else f"{text[:12]}... ({len(text)} digits)"
    if isinstance(v, numbers.Real):
        return json.dumps(float(v))
    if isinstance(v, str):
        text, whole = _escaped(v)
        return f'"{text}"' if whole else f'"{text}..." ({len(v)} characters)'
    if isinstance(v, (list, tuple, dict)):
        if depth <= 0 or not v:
            return ("[]" if isinstance(v, (list, tuple)) else "{}") if not v else (
                "[...]" if isinstance(v, (list, tuple)) else "{...}")
        if isinstance(v, dict):
            parts = [f"{shown(str(k), 0)}: {shown(x, depth - 1)}"
                     for k, x in list(v.items())[:_QUOTE_ITEMS]]
        else:
            parts = [shown(x, depth - 1) for x in list(v[:_QUOTE_ITEMS])]
        more = ", ..." if len(v) > _QUOTE_ITEMS else ""
        ends = "{}" if isinstance(v, dict) else "[]"
        return f"{ends[0]}{', '.join(parts)}{more}{ends[1]}"
    return f"<{type(v).__name__}>"


def shown_key(k: Any) -> str:
    """An object key as a field path shows it: bounded, ASCII, no quotes."""
    if not isinstance(k, str):
        return shown(k)
    text, whole = _escaped(k)
    return text if whole else text + "..."


def _escaped(text: str) -> tuple[str, bool]:
    """``text`` JSON-escaped (ASCII) up to :data:`_QUOTE_CHARS` output characters; whether
    all of it fitted."""
    out, used = [], 0
    for ch in text[:_QUOTE_CHARS]:
        piece = json.dumps(ch)[1:-1]
        used += len(piece)
        if used > _QUOTE_CHARS:
            return "".join(out), False
        out.append(piece)
    return "".join(out), len(text) <= _QUOTE_CHARS


class ParaloopError(ValueError):
    """Base class: ``reason`` is a short code, the message says what and why; ``param`` names
    the argument the error is about (``rho``, ``fixed``, ``L``, ...) when it is one, so that a
    front end can name the design field it came from (:meth:`in_field`)."""

    reason = "invalid"
    param: str | None = None

    def __init__(self, message: str, reason: str | None = None, param: str | None = None):
        super().__init__(message)
        if reason is not None:
            self.reason = reason
        if param is not None:
            self.param = param

    def in_field(self, field: str) -> ParaloopError:
        """This error, its message prefixed by the design ``field`` it came from (in place)."""
        self.args = (f"{field}: {self}",)
        self.field = field
        return self


class NonGenericMotionError(ParaloopError):
    """The motion polynomial is not generic (reasons: ``real-root``, ``repeated-factor``,
    ``singular-remainder``, ``translational-factor``, ``not-motion``, ``singular-leading``)."""

    reason = "non-generic"


class InterpolationError(ParaloopError):
    """Four-pose interpolation impossible (reasons: ``coincident``, ``rank``, ``no-real``,
    ``zero-pitch``, ``bad-mu``)."""

    reason = "interpolation"


class DesignFileError(ParaloopError):
    """A design file is malformed; ``field`` names the offending JSON path."""

    reason = "design-file"

    def __init__(self, field: str, message: str):
        super().__init__(f"{field}: {message}")
        self.field, self.message = field, message

    def __reduce__(self):
        # pickle rebuilds an exception from its args (here the joined text), not from the two
        # parts __init__ takes; a batch task's error travels back from a worker process
        return type(self), (self.field, self.message), self.__dict__


class RealizationError(ParaloopError):
    """No collision-free realization (reasons: ``bad-parameters``, ``singular-loop``,
    ``cap-reached``); the message says what was tried."""

    reason = "realization"


class FitError(ParaloopError):
    """Motion evolution refused or failed (reasons: ``too-few-poses``, ``duplicate-poses``,
    ``not-finite``, ``no-convergence``)."""

    reason = "fit"


class FabricationError(ParaloopError):
    """Design-space carving or part generation refused (reasons: ``bad-parameters``,
    ``empty-space``, ``not-watertight``)."""

    reason = "fabrication"


class EndEffectorError(ParaloopError):
    """End-effector mesh refused (reasons: ``load``, ``not-triangles``, ``bad-index``,
    ``not-finite``, ``degenerate``, ``too-large``, ``bad-parameters``)."""

    reason = "end-effector"


class NumericalError(ParaloopError):
    """float64 cannot represent a value of this design's solution (reason ``not-finite``): a
    value came out NaN or infinite; the message names where."""

    reason = "not-finite"
