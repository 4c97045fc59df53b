"""Progress bars of a long command's steps (:data:`simgap.core.progress.ProgressCallback`)."""

from __future__ import annotations

import time
from dataclasses import dataclass
from types import TracebackType

from rich.console import Console
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TaskID,
    TextColumn,
    TimeElapsedColumn,
)

#: Seconds between two plain progress lines of a step when not on a terminal.
PLAIN_INTERVAL_S = 30.0


@dataclass
class _PlainStep:
    """The step a plain display follows: its name, start and last line (monotonic s), count."""

    name: str
    start: float
    last: float
    done: int
    total: int | None


class StepBars:
    """One rich progress bar per step on a terminal, else plain lines; on stderr, when asked.

    Called as ``bars(step, done, total)`` (total None: a pulsing bar until the next step). The
    display starts at the first call, so a progress display of the steps before (the
    simulation's) has ended by then; use it as a context manager to stop it. Not on a terminal
    (a CI log, a notebook cell), each step prints a line when it starts, every
    :data:`PLAIN_INTERVAL_S` and when it ends: ``step: done/total after N s, about M s left``.

    Parameters
    ----------
    show : bool
        ``--progress``; False (``--no-progress``) shows nothing.
    console : rich.console.Console, optional
        Where to draw (default: stderr): bars on a terminal, plain lines elsewhere.
    """

    def __init__(self, show: bool, console: Console | None = None) -> None:
        self.console = console or Console(stderr=True)
        self.show = show and self.console.is_terminal
        self.plain = show and not self.console.is_terminal
        self._bars: Progress | None = None
        self._tasks: dict[str, TaskID] = {}
        self._last: str | None = None
        self._line: _PlainStep | None = None

    def __call__(self, step: str, done: int, total: int | None) -> None:
        """Show that ``done`` of ``total`` units of ``step`` are done."""
        if self.plain:
            self._plain(step, done, total)
        if not self.show:
            return
        if self._bars is None:
            self._bars = Progress(
                TextColumn("[bold]{task.description}"),
                BarColumn(),
                MofNCompleteColumn(),
                TimeElapsedColumn(),
                console=self.console,
            )
            self._bars.start()
        if step not in self._tasks:
            self._finish_last()
            self._tasks[step] = self._bars.add_task(step, total=total)
        self._bars.update(self._tasks[step], completed=done, total=total)
        self._last = step

    def _plain(self, step: str, done: int, total: int | None) -> None:
        """A plain line at a step's start, every :data:`PLAIN_INTERVAL_S` and at its end."""
        now = time.monotonic()
        line = self._line
        if line is None or line.name != step:
            self._end_plain()
            self._line = _PlainStep(step, now, now, done, total)
            self._print_line(step, done, total, 0.0)
            return
        line.done, line.total = done, total
        finished = total is not None and done >= total
        if finished or now - line.last >= PLAIN_INTERVAL_S:
            self._print_line(step, done, total, now - line.start)
            line.last = now
        if finished:
            self._line = None

    def _end_plain(self) -> None:
        """The last line of an unfinished plain step (its count when the next one starts)."""
        if self._line is not None:
            line, self._line = self._line, None
            self._print_line(line.name, line.done, line.total, time.monotonic() - line.start)

    def _print_line(self, step: str, done: int, total: int | None, elapsed: float) -> None:
        """``step: done/total after N s, about M s left`` (plain text, no markup)."""
        left = ""
        if total and 0 < done < total:
            left = f", about {elapsed / done * (total - done):.0f} s left"
        count = f"{done}/{total}" if total is not None else f"{done}"
        self.console.print(f"{step}: {count} after {elapsed:.0f} s{left}", markup=False)

    def _finish_last(self) -> None:
        """Mark the previous step done (a step of unknown length stops pulsing)."""
        if self._bars is None or self._last is None:
            return
        task = self._tasks[self._last]
        done = next(t.completed for t in self._bars.tasks if t.id == task)
        self._bars.update(task, total=done, completed=done)

    def close(self) -> None:
        """Stop the display (the bars stay on the screen)."""
        self._end_plain()
        if self._bars is not None:
            self._finish_last()
            self._bars.stop()
            self._bars, self._tasks, self._last = None, {}, None

    def __enter__(self) -> StepBars:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()
