"""Progress display of the fit's stages, for the command line and the demo."""

from __future__ import annotations

import time
from collections.abc import Callable

#: said once, when the first kernel of a run is compiled rather than loaded from the cache
COMPILING = (
    "compiling meshfit's numba kernels for this machine (a first run: about a minute on two "
    "cores; they are cached, and later runs skip this)"
)


#: counts (cached, length) of the compile-ahead queue this process takes part in, or None:
#: set by :func:`meshfit._compile_ahead.claiming` (which sits above this module)
queue_counts: Callable[[], tuple[int, int] | None] | None = None


class stage_progress:
    """A rich progress display with one bar per pipeline stage (stderr; silent if quiet).

    While it is open, numba compiling a kernel (a first run, or a new machine; a kernel
    loaded from its cache is not compiled) shows as a ``kernels`` line with the seconds
    spent, and `COMPILING` is printed once: otherwise a first run sits silently in a stage
    for a minute. The line counts the kernels of the run's compile-ahead queue cached so
    far by every process compiling them, out of the queue's length (how far the first run
    has to go; :data:`queue_counts`), or, without a queue, the kernels compiled here.
    """

    def __init__(self, quiet: bool = False) -> None:
        from rich.console import Console
        from rich.progress import BarColumn, MofNCompleteColumn, Progress, TimeElapsedColumn

        self.console = Console(stderr=True, quiet=quiet)
        self.bar = Progress(
            "[bold]{task.description:<13}",
            BarColumn(),
            MofNCompleteColumn(),
            TimeElapsedColumn(),
            console=self.console,
            transient=False,
            disable=quiet,
        )
        self.tasks: dict[str, int] = {}
        self.compiled = 0
        self.compile_seconds = 0.0
        self._listener = _Compiling(self._compiling)

    def __enter__(self):
        from numba.core import event

        self.bar.__enter__()
        event.register("numba:compile", self._listener)
        return self

    def __exit__(self, *exc):
        from numba.core import event

        event.unregister("numba:compile", self._listener)
        return self.bar.__exit__(*exc)

    def __call__(self, stage: str, done: int, total: int) -> None:
        if stage not in self.tasks:
            self.tasks[stage] = self.bar.add_task(stage, total=max(total, 1))
        self.bar.update(self.tasks[stage], completed=done, total=max(total, 1))
        if "kernels" in self.tasks:  # the other process compiles while this one works
            self._show_kernels()

    def _compiling(self, seconds: float | None) -> None:
        """A kernel's compilation began (``seconds`` None) or ended after ``seconds``."""
        if seconds is None:
            if self.compiled == 0:
                self.console.print(COMPILING)
                self.tasks["kernels"] = self.bar.add_task("kernels", total=None)
                self._show_kernels()
            return
        self.compiled += 1
        self.compile_seconds += seconds
        self._show_kernels()

    def _show_kernels(self) -> None:
        queued = queue_counts() if queue_counts is not None else None
        done, total = queued if queued is not None else (self.compiled, None)
        self.bar.update(
            self.tasks["kernels"],
            completed=done,
            total=total,
            description=f"kernels ({self.compile_seconds:.0f} s compiling)",
        )


def _Compiling(show):
    """A numba event listener calling ``show(None)`` when a kernel's compilation begins and
    ``show(seconds)`` when it ends (the kernels it compiles on the way count as its own)."""
    from numba.core import event

    class Compiling(event.Listener):
        def __init__(self) -> None:
            self.depth = 0
            self.start = 0.0

        def on_start(self, ev) -> None:
            if self.depth == 0:
                self.start = time.perf_counter()
                show(None)
            self.depth += 1

        def on_end(self, ev) -> None:
            self.depth -= 1
            if self.depth == 0:
                show(time.perf_counter() - self.start)

    return Compiling()
