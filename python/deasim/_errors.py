"""The exceptions of deasim: every failure keeps its kind."""

from typing import Any, Optional


class DeasimError(Exception):
    """Base of every deasim error.

    ``results`` holds the accepted steps of a run that started, else None.
    """

    key: Optional[str] = None
    reason: Optional[str] = None
    results: Any = None


class ScenarioError(DeasimError, ValueError):
    """The scenario or an override is wrong; ``key`` is the dotted key path, where known."""


class SolveError(DeasimError, RuntimeError):
    """A stage failed; ``reason`` says why and ``results`` hold every step accepted before."""


class DeasimIOError(DeasimError, OSError):
    """A file could not be read or written."""


class DeasimFileNotFoundError(DeasimIOError, FileNotFoundError):
    """A file to read does not exist (also a ``FileNotFoundError``)."""


class Interrupted(DeasimError):
    """The run was stopped on request (the progress callback returned False); ``results`` hold
    every step accepted before."""
