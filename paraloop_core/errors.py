"""Exceptions with a machine-readable ``reason``; all are ``ValueError`` (bad or degenerate
input)."""

from __future__ import annotations


class ParaloopError(ValueError):
    """Base class: ``reason`` is a short code, the message says what and why."""

    reason = "invalid"

    def __init__(self, message: str, reason: str | None = None):
        super().__init__(message)
        if reason is not None:
            self.reason = reason


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
