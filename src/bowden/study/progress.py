"""Progress display for long stages (rich), silent when disabled (tests, pipes)."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn


class StageProgress:
    """One progress bar per stage, on stderr so stdout stays clean for the summary."""

    def __init__(self, *, enabled: bool = True, console: Console | None = None) -> None:
        self.enabled = enabled
        self.console = console if console is not None else Console(stderr=True)

    @contextmanager
    def bar(self, description: str, total: int) -> Iterator[Callable[[int], None]]:
        """A bar to ``total``; yields ``advance(done)`` taking the absolute count done."""
        if not self.enabled:
            yield lambda _done: None
            return
        columns = (
            TextColumn("{task.description}"),
            BarColumn(),
            MofNCompleteColumn(),
            TimeElapsedColumn(),
        )
        with Progress(*columns, console=self.console, transient=False) as progress:
            task = progress.add_task(description, total=total)
            yield lambda done: progress.update(task, completed=done)
            progress.update(task, completed=total)

    @contextmanager
    def spinner(self, description: str) -> Iterator[None]:
        if not self.enabled:
            yield
            return
        with self.console.status(description):
            yield
        self.console.print(f"[green]✓[/green] {description}")
