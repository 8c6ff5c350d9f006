"""Running a pipeline's stages: each one timed, its progress reported, and a
chance to cancel before it starts.

The field pipeline (pipeline.py: validate -> tetmesh -> ... -> integrate)
runs its stages through one ``Stages``; a later pipeline (hex meshing) runs
its own the same way.  The caller names the stages and weighs them: a
stage's weight is the share of a typical run it takes, and the progress
fraction reported after it grows by that much.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from contextlib import contextmanager

from .errors import Cancelled

Progress = Callable[[str, float, str], None]
"""progress(stage, fraction done in [0, 1], message)."""


class Stages:
    """Times named stages, reports progress and checks for cancellation.

    Parameters
    ----------
    weights : mapping of str to float
        Share of the whole run each stage takes (they sum to at most 1); a
        stage without a weight adds nothing to the progress fraction.
    seconds : dict of str to float
        Receives the seconds of each stage under its name (added to an
        entry that is already there, so a stage may run in several parts).
    progress : callable(stage, fraction, message) or None
        Called before and after every stage.
    cancel : callable() -> bool, or None
        Asked before every stage; True raises ``errors.Cancelled``.
    start : float
        The fraction already done when this run continues an earlier one.
    """

    def __init__(self, weights: Mapping[str, float], seconds: dict[str, float], progress: Progress | None = None,
                 cancel: Callable[[], bool] | None = None, start: float = 0.0):
        self.weights = weights
        self.seconds = seconds
        self.progress = progress
        self.cancel = cancel
        self.done = float(start)

    def run(self, name: str, fn: Callable, *args, **kw):
        """``fn(*args, **kw)`` as stage ``name``; returns what fn returns.

        Raises
        ------
        Cancelled
            If ``cancel()`` is true before the stage starts.
        """
        if self.cancel is not None and self.cancel():
            raise Cancelled()
        self.say(name, f"{name}...")
        with self.timed(name):
            out = fn(*args, **kw)
        self.done = min(1.0, self.done + self.weights.get(name, 0.0))
        self.say(name, f"{name} done")
        return out

    @contextmanager
    def timed(self, name: str):
        """Add the seconds of a block to stage ``name`` (no progress, no
        cancellation: for work that belongs to a stage but runs outside
        ``run``)."""
        t = time.perf_counter()
        try:
            yield
        finally:
            self.seconds[name] = self.seconds.get(name, 0.0) + time.perf_counter() - t

    def say(self, name: str, message: str, fraction: float | None = None) -> None:
        """Report ``message`` for stage ``name`` at ``fraction`` (default:
        the fraction done so far)."""
        if self.progress is not None:
            self.progress(name, self.done if fraction is None else fraction, message)
