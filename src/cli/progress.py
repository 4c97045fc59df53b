"""Progress bars of a long command's steps (:data:`simgap.core.progress.ProgressCallback`)."""

from __future__ import annotations

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


class StepBars:
    """One rich progress bar per step, on stderr, shown only on a terminal and when asked.

    Called as ``bars(step, done, total)`` (total None: a pulsing bar until the next step). The
    display starts at the first call, so a progress display of the steps before (the
    simulation's) has ended by then; use it as a context manager to stop it.

    Parameters
    ----------
    show : bool
        ``--progress``; False (``--no-progress``) shows nothing.
    console : rich.console.Console, optional
        Where to draw (default: stderr); nothing is drawn unless it is a terminal.
    """

    def __init__(self, show: bool, console: Console | None = None) -> None:
        self.console = console or Console(stderr=True)
        self.show = show and self.console.is_terminal
        self._bars: Progress | None = None
        self._tasks: dict[str, TaskID] = {}
        self._last: str | None = None

    def __call__(self, step: str, done: int, total: int | None) -> None:
        """Show that ``done`` of ``total`` units of ``step`` are done."""
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

    def _finish_last(self) -> None:
        """Mark the previous step done (a step of unknown length stops pulsing)."""
        if self._bars is None or self._last is None:
            return
        task = self._tasks[self._last]
        done = next(t.completed for t in self._bars.tasks if t.id == task)
        self._bars.update(task, total=done, completed=done)

    def close(self) -> None:
        """Stop the display (the bars stay on the screen)."""
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
