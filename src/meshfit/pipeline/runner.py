"""The one runner of the fit's stages: content keys, the stage cache, progress, timings.

A stage (:class:`Stage`) names the earlier stages its result depends on and the option group
it reads; its content key hashes those keys and that group, so a stage is recomputed exactly
when something it reads changed. The runner loops over the stages; with a cache folder each
result is saved under its key, and with ``resume`` a saved result is loaded instead of
computed. A stage marked ``background`` runs on a thread beside the stages after it (writing
files overlaps with the error searches); its result is joined before the runner returns.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from typing import Any

from meshfit._threads import map_threads
from meshfit.pipeline.store import content_key

Progress = Callable[[str, int, int], None]


class Context:
    """What the stages share: the inputs, each stage's outputs by name, keys and timings.

    A value may be a thunk (:meth:`lazy`), made on first :meth:`get`, or a future (a
    background stage's or a side computation's), waited for on first :meth:`get`.
    """

    def __init__(self, options: Any, workers: int, progress: Progress | None = None) -> None:
        self.options = options
        self.workers = workers
        self.progress = progress
        self.values: dict[str, Any] = {}
        self.keys: dict[str, str] = {}
        self.info: dict[str, dict[str, Any]] = {}
        self.notes: list[str] = []
        #: per stage: whether the runner will load it from the cache (set by the runner)
        self.saved: dict[str, bool] = {}
        #: the cache file of a stage by name and suffix (None without a cache)
        self.path: Callable[[str, str], Path | None] = lambda name, suffix: None
        #: where the per-patch stages send their work as Dask tasks
        #: (:class:`meshfit.pipeline.cluster.PatchTasks`); None: the context's threads
        self.tasks: Any = None
        self._lazy: dict[str, Callable[[], Any]] = {}

    def __getitem__(self, name: str) -> Any:
        return self.get(name)

    def __setitem__(self, name: str, value: Any) -> None:
        self.values[name] = value
        self._lazy.pop(name, None)

    def __contains__(self, name: str) -> bool:
        return name in self.values or name in self._lazy

    def get(self, name: str) -> Any:
        if name not in self.values and name in self._lazy:
            self.values[name] = self._lazy.pop(name)()
        value = self.values[name]
        if isinstance(value, Future):
            value = value.result()
            self.values[name] = value
        return value

    def lazy(self, name: str, make: Callable[[], Any]) -> None:
        """``name`` made by ``make()`` when first read (never, if nothing reads it)."""
        self.values.pop(name, None)
        self._lazy[name] = make

    def tick(self, stage: str, done: int, total: int) -> None:
        if self.progress is not None:
            self.progress(stage, done, total)

    def map(self, fn: Callable, items: Sequence, stage: str, cost: Sequence[float] | None = None):
        """``[fn(x) for x in items]`` on the context's threads, in order, with progress."""
        self.tick(stage, 0, len(items))
        return map_threads(
            fn, items, self.workers, cost=cost, progress=lambda d, n: self.tick(stage, d, n)
        )


class Stage:
    """One step of the fit.

    Subclasses set ``name``, ``inputs`` and ``outputs`` (context values read and made;
    the runner checks both), ``after`` (the stages whose keys feed this one's) and
    ``suffix`` (of the cache file), and implement :meth:`run` (compute the outputs into the
    context), :meth:`save` and :meth:`load` (the cache file; :meth:`load` returns False when
    the file cannot stand for a run, e.g. files it vouches for are gone), and optionally
    :meth:`group` (the option group the stage reads) and :meth:`extra` (more key parts).
    """

    name = ""
    #: context values the stage reads, and those it leaves for the later stages
    inputs: tuple[str, ...] = ()
    outputs: tuple[str, ...] = ()
    after: tuple[str, ...] = ()
    suffix: str | None = ".npz"
    background = False

    def group(self, ctx: Context) -> Any:
        return None

    def extra(self, ctx: Context) -> Any:
        return None

    def key(self, ctx: Context) -> str:
        from meshfit.pipeline.options import stage_key

        g = self.group(ctx)
        return content_key(
            self.name,
            *(ctx.keys[a] for a in self.after),
            stage_key(g) if g is not None else None,
            self.extra(ctx),
        )

    def run(self, ctx: Context) -> None:
        raise NotImplementedError

    def save(self, ctx: Context, path: Path) -> None:
        raise NotImplementedError

    def load(self, ctx: Context, path: Path) -> bool:
        raise NotImplementedError

    def prepare(self, ctx: Context) -> None:
        """Work done on the calling thread before a background stage starts (imports of
        extension modules: loading one beside a numba kernel load can deadlock)."""

    def facts(self, ctx: Context) -> dict[str, Any]:
        """Extra entries of the stage's row in ``summary["stages"]``."""
        return {}


class Runner:
    """Runs stages in order over a context, with an optional cache folder.

    Parameters
    ----------
    cache : Path, optional
        Folder of the stage files (``<stage>-<key><suffix>``); None: nothing is cached.
    resume : bool
        Load a stage's saved result when its key matches instead of computing it.
    """

    def __init__(self, cache: Path | None = None, resume: bool = False) -> None:
        self.cache = cache
        self.resume = resume
        if cache is not None:
            cache.mkdir(parents=True, exist_ok=True)

    def path(self, stage: Stage, key: str) -> Path | None:
        """The stage's cache file for ``key`` (None without a cache or for an uncached
        stage, whose ``suffix`` is None)."""
        if self.cache is None or stage.suffix is None:
            return None
        return self.cache / f"{stage.name}-{key}{stage.suffix}"

    def saved(self, stage: Stage, key: str) -> bool:
        """Whether a resumed run finds the stage's file for ``key``."""
        path = self.path(stage, key)
        return bool(self.resume and path is not None and path.is_file())

    def _one(self, stage: Stage, ctx: Context, key: str) -> None:
        t0 = time.perf_counter()
        missing = [n for n in stage.inputs if n not in ctx]
        if missing:
            raise RuntimeError(f"stage {stage.name} runs before its inputs {missing} exist")
        path = self.path(stage, key)
        cached = path is not None and self.saved(stage, key) and _loaded(stage, ctx, path)
        if not cached:
            stage.run(ctx)
            if path is not None:
                stage.save(ctx, path)
        missing = [n for n in stage.outputs if n not in ctx]
        if missing:
            raise RuntimeError(f"stage {stage.name} left its outputs {missing} unmade")
        ctx.info[stage.name] = {
            "seconds": round(time.perf_counter() - t0, 4),
            "cached": cached,
            **stage.facts(ctx),
        }
        ctx.tick(stage.name, 1, 1)

    def run(self, stages: Sequence[Stage], ctx: Context) -> Context:
        """Run ``stages`` in order; background stages beside the later ones.

        Every key is known before the first stage runs (keys depend on options and earlier
        keys, never on results), so a stage can ask whether a later one will be loaded
        (``ctx.saved``) and skip work only that stage needs.
        """
        for stage in stages:
            ctx.keys[stage.name] = stage.key(ctx)
        ctx.saved = {s.name: self.saved(s, ctx.keys[s.name]) for s in stages}
        ctx.path = lambda name, suffix: (
            None if self.cache is None else self.cache / f"{name}-{ctx.keys[name]}{suffix}"
        )
        pool = ThreadPoolExecutor(max_workers=2)
        pending: list[Future] = []
        try:
            for stage in stages:
                key = ctx.keys[stage.name]
                if stage.background:
                    stage.prepare(ctx)
                    pending.append(pool.submit(self._one, stage, ctx, key))
                else:
                    self._one(stage, ctx, key)
        finally:
            pool.shutdown(wait=True)
        for f in pending:
            f.result()  # re-raises a background stage's error
        return ctx


def _loaded(stage, ctx, path: Path) -> bool:
    """Whether the stage's cache at ``path`` was read; a damaged one (truncated, edited,
    another format) counts as missing: the stage runs again and writes it anew."""
    from meshfit.errors import MeshfitError

    try:
        return bool(stage.load(ctx, path))
    except (MeshfitError, ValueError, KeyError, TypeError, IndexError, OSError, EOFError):
        return False
