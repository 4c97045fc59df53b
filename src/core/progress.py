"""Progress of a long computation, reported to whoever called it (no display in this layer).

A caller that shows progress (the command line, with a bar) passes a :data:`ProgressCallback`
down; the computation counts its steps with a :class:`Steps`. Without a callback nothing is
reported, so libraries and tests stay quiet.

Examples
--------
>>> seen = []
>>> steps = Steps(lambda step, done, total: seen.append((step, done, total)))
>>> steps.start("fitting candidates", 2)
>>> steps.advance(); steps.advance()
>>> seen
[('fitting candidates', 0, 2), ('fitting candidates', 1, 2), ('fitting candidates', 2, 2)]
"""

from __future__ import annotations

from collections.abc import Callable

#: ``(step, done, total)``: a step's name, its units of work done so far and how many there are
#: (None when not known in advance, as in a search that stops when nothing improves).
ProgressCallback = Callable[[str, int, "int | None"], None]


class Steps:
    """Counts the units of work of one step at a time and reports them to a callback.

    Parameters
    ----------
    report : ProgressCallback, optional
        Called when a step starts (done 0) and after every unit of work; None: silent.
    """

    def __init__(self, report: ProgressCallback | None = None) -> None:
        self.report = report
        self.step = ""
        self.done = 0
        self.total: int | None = None

    def start(self, step: str, total: int | None = None) -> None:
        """Start ``step`` with ``total`` units of work (None: unknown)."""
        self.step, self.done, self.total = step, 0, total
        if self.report is not None:
            self.report(step, 0, total)

    def advance(self) -> None:
        """One more unit of work of the current step is done (ignored before any step)."""
        if not self.step:
            return
        self.done += 1
        if self.report is not None:
            self.report(self.step, self.done, self.total)
