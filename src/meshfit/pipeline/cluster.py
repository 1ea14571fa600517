"""The per-patch work of one fit as Dask tasks: spring meshes, spline fits, displacement
maps and error searches.

:func:`meshfit.fit` with ``cluster`` runs each patch's spring mesh, spline fit,
displacement map and error searches as a task on dask.distributed workers: a LocalCluster
of worker processes on 127.0.0.1, or a running scheduler. Task inputs are passed by
reference: the client writes each task's inputs once to a scratch folder of ``.npz`` files
(``tasks/`` in the fit's stage cache with an output folder, else a temporary folder;
removed when the fit ends) and a task receives that file's path and small options, never a
pickled mesh. Results come back as arrays.

A worker lost mid-run (killed, or past its memory limit) has its tasks run again elsewhere,
up to ``retries`` extra times. A task reads only its own files and computes the same bytes
on every attempt, so the fit is the same bytes as a run without a lost worker.

What stays on the client, and why:

- the layout and the cut: graph work over the whole mesh;
- the boundary curves that pin the patches' splines, fitted to the spring meshes of the
  patches on each curve (:func:`meshfit.stitch.layout.boundary_pins`; a task gets its
  patch's pinned rows), and the G1 stitch, which couples neighbouring patches;
- stitching, the exports and the report: they read every patch at once, as do the error
  figures, which the client makes from the tasks' distances.

The error searches split by patch without changing a distance (:func:`scan_errors_task`,
:func:`texel_task`): a texel's distance to the scan is a least distance over the scan's
triangles whichever task searches it; a scan vertex's distance is to all patches' grids
together (a vertex by a seam may be nearest its neighbour's), so each vertex is searched in
its own patch's grid and then only in the neighbours' grids that may be nearer
(:func:`meshfit.pipeline.measure.nearest_grid_distances`), a task reading those grids
alone.

A map at a finer resolution than its spring grid (matched map shapes) moves each texel to
its closest point on the whole scan (:func:`meshfit.displacement.refine_on_scan`): the
closest point may lie beyond the patch, and which triangle answers depends on the whole
scan's search tree. Its tasks read the scan, its tree and its face normals from ``.npy``
files the client writes once (``scan/``), memory-mapped: the workers of one machine share
one copy through the page cache, and a task answers exactly as the client would.
"""

from __future__ import annotations

import contextlib
import numbers
import os
import shutil
import tempfile
import threading
import uuid
from collections.abc import Callable, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from meshfit.errors import InputError, MeshfitError
from meshfit.pipeline.store import load_npz, save_npz

__all__ = [
    "CONNECT_SECONDS",
    "LOCAL_CLUSTER_FACES",
    "MEMORY_LIMIT",
    "RETRIES",
    "ClusterOptions",
    "PatchTasks",
    "fit_file_task",
    "map_file_task",
    "patch_tasks",
    "piece_map_task",
    "resolve_cluster",
    "scan_errors_task",
    "spring_file_task",
    "texel_task",
    "warm_task",
]

#: with ``cluster="auto"``, meshes of at least this many faces run their per-patch work on a
#: LocalCluster; None: never (threads of the calling process). Off: on one machine the
#: threads already use every core (the kernels release the GIL), and a LocalCluster adds its
#: start, the workers' kernel loads and the scratch files (benchmarks/scale.py measures both)
LOCAL_CLUSTER_FACES: int | None = None
#: memory limit of each LocalCluster worker (a worker past it is restarted, its tasks re-run)
MEMORY_LIMIT = "4GiB"
#: extra attempts of a task that failed or whose worker was lost
RETRIES = 3
#: seconds to wait for a scheduler to answer before giving up
CONNECT_SECONDS = 10.0
#: the scratch folder's name in the fit's stage cache
SCRATCH = "tasks"


@dataclass(frozen=True)
class ClusterOptions:
    """Where and how the per-patch tasks of one fit run.

    Attributes
    ----------
    processes : int, optional
        Worker processes of a LocalCluster on 127.0.0.1 (one thread each, no dashboard);
        default: one per core. Ignored with ``scheduler``.
    scheduler : str, optional
        Address of a running Dask scheduler (``"tcp://host:8786"``). Its workers must read
        the fit's scratch folder: give the fit an ``out`` folder on a file system they share.
    memory_limit : str or int
        Memory limit per LocalCluster worker (default `MEMORY_LIMIT`; Dask's notation,
        ``"4GiB"`` or ``"auto"``, or bytes).
    retries : int
        Extra attempts of a task that failed or whose worker was lost (default `RETRIES`).
    """

    processes: int | None = None
    scheduler: str | None = None
    memory_limit: str | int = MEMORY_LIMIT
    retries: int = RETRIES

    def __post_init__(self) -> None:
        if self.processes is not None and not _count(self.processes, 1):
            raise InputError(f"processes must be an integer >= 1, got {self.processes!r}")
        if self.scheduler is not None and (
            not isinstance(self.scheduler, str) or not self.scheduler.strip()
        ):
            raise InputError(f"scheduler must be an address, got {self.scheduler!r}")
        if not _count(self.retries, 0):
            raise InputError(f"retries must be an integer >= 0, got {self.retries!r}")
        if not _memory(self.memory_limit):
            raise InputError(
                f"memory_limit must be a size such as '4GiB' or a number of bytes, got "
                f"{self.memory_limit!r}"
            )


def _memory(x: Any) -> bool:
    """Whether ``x`` is a memory size Dask reads: ``"4GiB"``, ``"auto"`` or bytes > 0."""
    if isinstance(x, str):
        from dask.utils import parse_bytes

        try:
            return x == "auto" or (bool(x.strip()) and parse_bytes(x) > 0)
        except (ValueError, TypeError):
            return False
    return _count(x, 1)


def _count(x: Any, least: int) -> bool:
    """Whether ``x`` is an integer (not a bool) of at least ``least``."""
    return not isinstance(x, bool) and isinstance(x, numbers.Integral) and int(x) >= least


def _is_client(x: Any) -> bool:
    return type(x).__module__.startswith("distributed") and hasattr(x, "submit")


def resolve_cluster(cluster: Any, n_faces: int) -> Any:
    """The ``cluster`` argument of :func:`meshfit.fit` as ClusterOptions, a
    ``distributed.Client`` or None (threads): ``"auto"`` is a LocalCluster from
    `LOCAL_CLUSTER_FACES` faces up; an int, that many LocalCluster processes; a str, a
    scheduler's address."""
    if isinstance(cluster, str) and cluster == "auto":
        big = LOCAL_CLUSTER_FACES is not None and n_faces >= LOCAL_CLUSTER_FACES
        return ClusterOptions() if big else None
    if cluster is None or isinstance(cluster, ClusterOptions) or _is_client(cluster):
        return cluster
    if isinstance(cluster, str):
        return ClusterOptions(scheduler=cluster)
    if _count(cluster, 1):
        return ClusterOptions(processes=int(cluster))
    raise InputError(
        "cluster must be 'auto', None, a number of worker processes (>= 1), a scheduler "
        f"address, ClusterOptions or a distributed.Client, got {cluster!r}"
    )


def patch_tasks(cluster: Any, n_faces: int, stage_cache: Path | None) -> PatchTasks | None:
    """The fit's :class:`PatchTasks` for its ``cluster`` argument (None: threads), started:
    a scheduler is reached now (an unreachable one is an InputError before any work), a
    LocalCluster starts on a thread while the layout is made."""
    spec = resolve_cluster(cluster, n_faces)
    if spec is None:
        return None
    tasks = PatchTasks(spec, None if stage_cache is None else stage_cache / SCRATCH)
    tasks.start()
    return tasks


class PatchTasks:
    """The Dask side of one fit: the client, the scratch folder and the per-patch tasks.

    Parameters
    ----------
    spec : ClusterOptions or distributed.Client
        Where the tasks run; a client given is used as it is and left open.
    scratch : Path, optional
        The scratch folder (made on first use, removed by :meth:`close`); default a
        temporary folder.
    """

    def __init__(self, spec: Any, scratch: Path | None = None) -> None:
        self.options = spec if isinstance(spec, ClusterOptions) else ClusterOptions()
        self._given = None if isinstance(spec, ClusterOptions) else spec
        self._scratch = scratch
        self._folder: Path | None = None
        self._start: Future | None = None
        self._owned: list = []  # what close() shuts: our client, then our LocalCluster
        self._checked = False
        self._token = uuid.uuid4().hex[:12]
        self._warming: list = []  # futures of the warm-up tasks (kept: a dropped one ends)

    # ------------------------------------------------------------------ the client
    def start(self) -> None:
        """Reach the scheduler now, or start the LocalCluster on a thread."""
        if self._given is not None:
            self._warm(self._given)
            return
        import distributed  # noqa: F401 (its modules, on this thread: see Stage.prepare)

        if self.options.scheduler is not None:
            self._client_now()
            return
        pool = ThreadPoolExecutor(max_workers=1)
        self._start = pool.submit(self._local)
        pool.shutdown(wait=False)

    def _client_now(self) -> None:
        from distributed import Client

        address = self.options.scheduler
        try:
            client = Client(address, timeout=CONNECT_SECONDS, set_as_default=False)
        except (OSError, ValueError, TypeError) as exc:
            why = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            raise InputError(f"cannot reach the Dask scheduler at {address!r}: {why}") from None
        self._owned.append(client)
        self._given = client
        self._warm(client)

    def _local(self):
        from distributed import Client, LocalCluster

        n = self.options.processes or os.cpu_count() or 1
        lc = LocalCluster(
            n_workers=n,
            threads_per_worker=1,
            processes=True,
            host="127.0.0.1",
            dashboard_address=None,
            # no dashboard; the scheduler's own HTTP routes (health, metrics) on a free
            # port, not on 8787, which another cluster may hold
            scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},
            memory_limit=self.options.memory_limit,
        )
        self._owned.append(lc)
        client = Client(lc, set_as_default=False)
        self._owned.insert(0, client)
        self._warm(client)
        return client

    def _warm(self, client) -> None:
        """One `warm_task` per worker, on its own, not waited for: a fresh worker imports the
        tasks' modules (seconds) while the client makes the layout, not when the first
        patch's task starts."""
        workers = sorted(client.scheduler_info()["workers"])
        self._warming = [
            client.submit(
                warm_task, key=f"meshfit-warm-{k}-{self._token}", workers=[w], priority=1e18
            )
            for k, w in enumerate(workers)
        ]

    @property
    def client(self):
        """The ``distributed.Client`` (waits for a LocalCluster still starting)."""
        if self._given is None and self._start is not None:
            try:
                self._given = self._start.result()
            except (OSError, RuntimeError, TimeoutError) as exc:
                why = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
                raise MeshfitError(f"the Dask LocalCluster did not start: {why}") from exc
        return self._given

    # ----------------------------------------------------------------- scratch files
    def folder(self) -> Path:
        """The scratch folder, made on first use (a leftover of a crashed run is emptied)."""
        if self._folder is None:
            if self._scratch is None:
                self._folder = Path(tempfile.mkdtemp(prefix="meshfit-tasks-"))
            else:
                shutil.rmtree(self._scratch, ignore_errors=True)
                self._scratch.mkdir(parents=True)
                self._folder = self._scratch
        return self._folder

    def _readable(self, path: Path) -> None:
        """InputError unless every worker of a cluster we did not start reads ``path`` (a
        remote worker sees only a file system it shares with the client)."""
        if self._checked or self._start is not None:
            return
        client = self.client
        try:
            client.wait_for_workers(1, timeout=CONNECT_SECONDS)
        except TimeoutError:
            raise InputError(
                f"the Dask scheduler at {client.scheduler.address} has no workers"
            ) from None
        seen = client.run(os.path.isfile, str(path))
        blind = sorted(w for w, ok in seen.items() if not ok)
        if blind:
            raise InputError(
                f"the Dask workers {', '.join(blind)} cannot read the fit's scratch folder "
                f"{path.parent}: give the fit an output folder on a file system they share"
            )
        self._checked = True

    # -------------------------------------------------------------------- the tasks
    def springs(self, patches: Sequence, options, progress: Callable[[int, int], None]) -> list:
        """Each patch's ``(grid, info)`` (:func:`meshfit.pipeline.spring_patch`), one task
        per patch reading the patch's ``spring-<p>.npz``."""
        folder = self.folder()
        paths = [save_npz(folder / f"spring-{p.index}.npz", _patch_arrays(p)) for p in patches]
        self._readable(paths[0])
        return self._run(
            "springs",
            [(spring_file_task, str(path), options) for path in paths],
            [p.mesh.n_faces for p in patches],
            progress,
        )

    def spring_files(
        self,
        paths: Sequence[Path],
        options,
        cost: Sequence[float],
        progress: Callable[[int, int], None],
    ) -> list:
        """Each patch's ``(grid, info)`` from patch files already written (a prepared scan's
        ``cut/patch-<p>.npz``), one task per file."""
        self._readable(Path(paths[0]))
        items = [(spring_file_task, str(path), options) for path in paths]
        return self._run("springs", items, cost, progress)

    def fits(
        self,
        grids: Sequence[NDArray[np.float64]],
        controls: Sequence[tuple[int, int]],
        pins: Sequence[dict[str, NDArray[np.float64]]],
        options,
        diag: float,
        progress: Callable[[int, int], None],
    ) -> list:
        """Each patch's spline and fit figures (:func:`meshfit.pipeline.stages.patch_fit`),
        one task per patch reading its ``fit-<p>.npz`` (its spring grid, control counts and
        pinned boundary rows)."""
        from meshfit.bspline import BSplineSurface

        folder = self.folder()
        paths = []
        for p, (g, c, pin) in enumerate(zip(grids, controls, pins, strict=True)):
            arrays = {"grid": g, "controls": np.asarray(c, dtype=np.int64)}
            arrays |= {f"pin_{side}": row for side, row in pin.items()}
            paths.append(save_npz(folder / f"fit-{p}.npz", arrays))
        self._readable(paths[0])
        items = [(fit_file_task, str(path), options, float(diag)) for path in paths]
        cost = [float(np.prod(c)) for c in controls]
        res = self._run("fit", items, cost, progress)
        return [(BSplineSurface(c, ku, kv), info) for (c, ku, kv), info in res]

    def maps(
        self,
        mesh,
        surfaces: Sequence,
        grids: Sequence[NDArray[np.float64]],
        shapes: Sequence[tuple[int, int]],
        kind: str,
        progress: Callable[[int, int], None],
        prepared: Path | None = None,
    ) -> list:
        """Each patch's displacement map and its texels' bounds
        (:func:`meshfit.pipeline.stages.patch_displacement`),
        one task per patch reading the patch's ``map-<p>.npz`` (and the scan, where the map is
        finer than the spring grid: ``mesh``, written once for the tasks, or with
        ``prepared``, the folder of a prepared scan, the patch's piece of it, which the task
        reads from the stores there)."""
        from meshfit.displacement import DisplacementMap

        folder = self.folder()
        finer = [tuple(sh) != tuple(g.shape[:2]) for g, sh in zip(grids, shapes, strict=True)]
        if prepared is not None:
            scan = None
        else:
            scan = _write_scan(mesh, folder / "scan") if any(finer) else None
        items: list[tuple[Any, ...]] = []
        for p, (s, g, sh) in enumerate(zip(surfaces, grids, shapes, strict=True)):
            path = save_npz(
                folder / f"map-{p}.npz",
                {
                    "grid": g,
                    "control_points": s.control_points,
                    "knots_u": s.knots_u,
                    "knots_v": s.knots_v,
                    "shape": np.asarray(sh, dtype=np.int64),
                },
            )
            if prepared is not None:
                piece = (str(prepared), p) if finer[p] else None
                items.append((piece_map_task, str(path), kind, piece))
            else:
                items.append((map_file_task, str(path), kind, str(scan) if finer[p] else None))
        self._readable(Path(items[0][1]))
        res = self._run("displacement", items, [sh[0] * sh[1] for sh in shapes], progress)
        return [(DisplacementMap(v, kind), b) for v, b in res]

    def texel_errors(
        self,
        prepared: Path,
        spline: Sequence[NDArray[np.float64]],
        displaced: Sequence[NDArray[np.float64]],
        bounds: Sequence[NDArray[np.float32]],
        near: float,
        progress: Callable[[int, int], None],
    ) -> list:
        """Each patch's :func:`meshfit.pipeline.prepared_stages.patch_errors` against the
        prepared scan in ``prepared``, one task per patch reading its piece of the scan and
        the ``texels-<q>.npz`` of its patch and of the neighbours its search needs."""
        from meshfit.pipeline.measure import grid_boxes

        folder = self.folder()
        boxes = np.stack([grid_boxes(list(spline)), grid_boxes(list(displaced))])
        paths = [
            save_npz(folder / f"texels-{p}.npz", {"spline": s, "displaced": d, "bounds": b})
            for p, (s, d, b) in enumerate(zip(spline, displaced, bounds, strict=True))
        ]
        self._readable(paths[0])
        items = [
            (texel_task, str(path), str(prepared), p, boxes, float(near))
            for p, path in enumerate(paths)
        ]
        cost = [float(np.prod(s.shape[:2])) for s in spline]
        return self._run("errors", items, cost, progress)

    def errors(
        self,
        mesh,
        owner: NDArray[np.int64],
        spline: Sequence[NDArray[np.float64]],
        displaced: Sequence[NDArray[np.float64]],
        bounds: Sequence[NDArray[np.float32]],
        near: float,
        progress: Callable[[int, int], None],
    ) -> list:
        """Each patch's :func:`scan_errors_task`: its texels' distances to ``mesh`` and those
        of the scan's vertices whose ``owner`` it is to the soup of all grids; one task per
        patch reading its ``texels-<p>.npz``, the neighbours' its search needs, and the scan
        (written once for the tasks, as for the maps)."""
        from meshfit.pipeline.measure import grid_boxes

        folder = self.folder()
        scan = _write_scan(mesh, folder / "scan")
        boxes = np.stack([grid_boxes(list(spline)), grid_boxes(list(displaced))])
        share = np.argsort(owner, kind="stable")
        cut = np.cumsum(np.bincount(owner, minlength=len(spline)))[:-1]
        paths = []
        for p, ids in enumerate(np.split(share, cut)):
            arrays: dict[str, NDArray] = {"spline": spline[p], "displaced": displaced[p]}
            arrays |= {"bounds": bounds[p], "vertices": ids}
            paths.append(save_npz(folder / f"texels-{p}.npz", arrays))
        self._readable(paths[0])
        items = [
            (scan_errors_task, str(path), str(scan), p, boxes, float(near))
            for p, path in enumerate(paths)
        ]
        cost = [float(np.prod(s.shape[:2])) for s in spline]
        return self._run("errors", items, cost, progress)

    def _run(self, stage: str, items: list, cost: Sequence[float], progress) -> list:
        """Submit one task per item ``(fn, *args)``, the costliest first; the results in
        order, ``progress(done, total)`` after each."""
        from distributed import as_completed

        client = self.client
        n = len(items)
        progress(0, n)
        futures = [
            client.submit(
                fn,
                *args,
                key=f"meshfit-{stage}-{p}-{self._token}",
                retries=self.options.retries,
                priority=float(cost[p]),
            )
            for p, (fn, *args) in enumerate(items)
        ]
        index = {f.key: p for p, f in enumerate(futures)}
        out: list = [None] * n
        try:
            for done, fut in enumerate(as_completed(futures, loop=client.loop), start=1):
                out[index[fut.key]] = self._result(fut, stage, index[fut.key])
                progress(done, n)
        except BaseException:
            client.cancel(futures)
            raise
        return out

    def _result(self, fut, stage: str, p: int):
        from distributed import KilledWorker

        try:
            return fut.result()
        except KilledWorker:
            raise MeshfitError(
                f"the {stage} task of patch {p} lost its worker on every attempt (a worker "
                f"past its memory limit, {self.options.memory_limit}, is restarted): give "
                "the workers more memory or use fewer processes per machine"
            ) from None

    def workers_peak_rss(self) -> int | None:
        """The peak resident set sizes of the workers summed, in bytes (None when they
        cannot be asked): of the fit's own LocalCluster, or of a running cluster's workers
        over their lifetimes (which may include other work)."""
        from meshfit._malloc import peak_rss

        try:
            peaks = self.client.run(peak_rss)
        except (OSError, TimeoutError, MeshfitError):
            return None
        values = [v for v in peaks.values() if v is not None]
        return int(sum(values)) if values else None

    # ---------------------------------------------------------------------- closing
    def close(self) -> None:
        """Remove the scratch folder; on a cluster we did not start, the workers let go of
        the scan; shut the client and LocalCluster we started."""
        try:
            if self._start is not None:
                with contextlib.suppress(MeshfitError):  # a failed start: nothing to shut
                    self.client  # noqa: B018 (waits for a LocalCluster still starting)
            elif self._given is not None:
                with contextlib.suppress(OSError, TimeoutError):
                    self._given.cancel(self._warming)  # (a worker lost before its warm-up)
                    if self._folder is not None:
                        self._given.run(forget_scans)
        finally:
            for obj in self._owned:
                with contextlib.suppress(OSError, TimeoutError, RuntimeError):
                    obj.close()
            if self._folder is not None:
                shutil.rmtree(self._folder, ignore_errors=True)

    def __enter__(self) -> PatchTasks:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def warm_task() -> None:
    """Task body run once on each worker as the fit reaches the cluster: imports the modules
    the tasks run."""
    import meshfit.bspline
    import meshfit.displacement
    import meshfit.pipeline.prepared_stages
    import meshfit.pipeline.springs
    import meshfit.pipeline.stages  # noqa: F401


def _patch_arrays(patch) -> dict[str, NDArray]:
    """A patch's :func:`meshfit.pipeline.patch_payload` as flat named arrays (an ``.npz``)."""
    from meshfit.pipeline.springs import patch_payload

    d = patch_payload(patch)
    arrays = {k: d[k] for k in ("vertices", "faces", "corners", "face_parent")}
    arrays |= {"source_face": d["source_face"], "source_bary": d["source_bary"]}
    arrays["index"] = np.array([d["index"]], dtype=np.int64)
    arrays |= {f"side_{s}": side for s, side in enumerate(d["sides"])}
    for k, (face, bary) in enumerate(d["features"]):
        arrays[f"feature_face_{k}"] = face
        arrays[f"feature_bary_{k}"] = bary
    arrays["feature_sides"] = np.asarray(d["feature_sides"], dtype=np.int64).reshape(-1, 2)
    return arrays


def spring_file_task(path: str, options) -> tuple[NDArray[np.float64], dict]:
    """Task body: the spring mesh of the patch in the ``.npz`` at ``path`` (written by
    :meth:`PatchTasks.springs`) with ``options`` (SpringOptions), as
    :func:`meshfit.pipeline.spring_task` returns it."""
    from meshfit.pipeline.springs import spring_task

    z = load_npz(Path(path))
    sides = z["feature_sides"]
    payload = {
        "index": int(z["index"][0]),
        "vertices": z["vertices"],
        "faces": z["faces"],
        "corners": z["corners"],
        "sides": [z[f"side_{s}"] for s in range(4)],
        "face_parent": z["face_parent"],
        "source_face": z["source_face"],
        "source_bary": z["source_bary"],
        "features": [
            (z[f"feature_face_{k}"], z[f"feature_bary_{k}"]) for k in range(sides.shape[0])
        ],
        "feature_sides": [(int(a), int(b)) for a, b in sides],
    }
    return spring_task((payload, options))


def fit_file_task(path: str, options, diag: float):
    """Task body: the spline of the patch in the ``.npz`` at ``path`` (written by
    :meth:`PatchTasks.fits`) as ``(control_points, knots_u, knots_v)``, and its fit figures."""
    from meshfit.pipeline.stages import patch_fit

    z = load_npz(Path(path))
    pins = {k[len("pin_") :]: v for k, v in z.items() if k.startswith("pin_")}
    controls = (int(z["controls"][0]), int(z["controls"][1]))
    s, info = patch_fit(z["grid"], controls, pins, options, diag)
    return (s.control_points, s.knots_u, s.knots_v), info


def map_file_task(
    path: str, kind: str, scan: str | None
) -> tuple[NDArray[np.float64], NDArray[np.float32]]:
    """Task body: the values of the displacement map described by the ``.npz`` at ``path``
    (written by :meth:`PatchTasks.maps`) and its texels' bounds
    (:func:`meshfit.pipeline.stages.texel_bounds`); ``scan``: the folder of the scan, for a
    map finer than its spring grid."""
    from meshfit.bspline import BSplineSurface
    from meshfit.pipeline.stages import patch_displacement

    z = load_npz(Path(path))
    surface = BSplineSurface(z["control_points"], z["knots_u"], z["knots_v"])
    shape = (int(z["shape"][0]), int(z["shape"][1]))
    mesh = None if scan is None else _scan(scan)
    dmap, bounds = patch_displacement(mesh, surface, z["grid"], shape, kind)
    return dmap.values, bounds


def piece_map_task(
    path: str, kind: str, piece: tuple[str, int] | None
) -> tuple[NDArray[np.float64], NDArray[np.float32]]:
    """Task body: as :func:`map_file_task`, the scan searched being ``piece = (folder, p)``:
    patch ``p``'s piece (its faces and their halo) of the prepared scan in ``folder``
    (:func:`meshfit.pipeline.prepare.prepare_out_of_core`), read from its stores."""
    from meshfit.bspline import BSplineSurface
    from meshfit.pipeline.stages import patch_displacement

    z = load_npz(Path(path))
    surface = BSplineSurface(z["control_points"], z["knots_u"], z["knots_v"])
    shape = (int(z["shape"][0]), int(z["shape"][1]))
    mesh = None if piece is None else piece_mesh(Path(piece[0]), int(piece[1]))
    dmap, bounds = patch_displacement(mesh, surface, z["grid"], shape, kind)
    return dmap.values, bounds


def texel_task(path: str, prepared: str, p: int, boxes: NDArray[np.float64], near: float):
    """Task body: :func:`meshfit.pipeline.prepared_stages.patch_errors` of patch ``p``, its
    texels in the ``.npz`` at ``path`` and every other patch's in the files beside it
    (written by :meth:`PatchTasks.texel_errors`; a neighbour's grid is read only when the
    search needs it)."""
    from meshfit.pipeline.prepared_stages import patch_errors

    return patch_errors(Path(prepared), p, _texels_beside(path), boxes, near)


def _texels_beside(path: str) -> Callable[[int, str], NDArray]:
    """``texels(q, kind)``: array ``kind`` of patch ``q``'s ``texels-<q>.npz`` in the folder
    of ``path`` (read when asked, so a task reads only the neighbours it needs)."""
    folder = Path(path).parent

    def texels(q: int, kind: str) -> NDArray:
        with np.load(folder / f"texels-{q}.npz", allow_pickle=False) as z:
            return z[kind]

    return texels


def scan_errors_task(path: str, scan: str, p: int, boxes: NDArray[np.float64], near: float):
    """Task body: patch ``p``'s error searches of an in-memory fit (:meth:`PatchTasks.errors`)
    as ``(spline texels to the scan, displaced texels to the scan, the patch's share of the
    scan's vertices to all spline grids, to all displaced grids)``; a displaced texel whose
    bound is within ``near`` keeps its bound (as :func:`meshfit.pipeline.measure.
    surface_distance` does)."""
    from meshfit.pipeline.measure import nearest_grid_distances

    texels = _texels_beside(path)
    mesh = _scan(scan)
    s, _ = triangle_distances_in(mesh, texels(p, "spline"))
    known = texels(p, "bounds").reshape(-1).astype(np.float64)
    d = known.copy()
    far = np.flatnonzero(~(known <= near))
    if far.size:
        d[far], _ = triangle_distances_in(mesh, texels(p, "displaced").reshape(-1, 3)[far])
    X = np.asarray(mesh.vertices[texels(p, "vertices")])
    vs = nearest_grid_distances(X, p, boxes[0], lambda q: texels(q, "spline"))
    vd = nearest_grid_distances(X, p, boxes[1], lambda q: texels(q, "displaced"))
    return s, d, vs, vd


def triangle_distances_in(mesh, points: NDArray) -> tuple[NDArray, NDArray]:
    """:func:`meshfit.mesh.locate.triangle_distances` of ``points`` to ``mesh`` with its
    own search tree."""
    from meshfit.mesh.locate import triangle_distances

    X = np.asarray(points).reshape(-1, 3)
    return triangle_distances(X, mesh.vertices, mesh.faces, tree=mesh.triangle_tree)


def piece_mesh(folder: Path, p: int):
    """Patch ``p``'s piece of the prepared scan in ``folder`` (its core and halo faces,
    :class:`meshfit.layout.outofcore.PatchStore`) as a mesh to search: closest points,
    face normals. Not checked again, nor split where it pinches (a search needs neither;
    checking builds an edge table, twice the time of the search tree)."""
    V, faces, _, _ = piece_arrays(folder, p)
    return _unchecked_mesh(V, faces)


def piece_arrays(folder: Path, p: int):
    """Patch ``p``'s piece of the prepared scan in ``folder`` as arrays: its vertices ``(k,
    3)``, its faces ``(m, 3)`` over them, the store vertex of each vertex ``(k,)`` and
    whether each face is in the patch's core ``(m,)`` (else in its halo)."""
    from meshfit.layout.outofcore import open_patch_store
    from meshfit.mesh.store import open_store

    store = open_store(folder / "mesh")
    pstore = open_patch_store(folder / "patches")
    if not 0 <= p < pstore.n_patches:
        raise InputError(f"patch {p} out of range ({pstore.n_patches} patches)")
    a, b = pstore.patch_start[p], pstore.patch_start[p + 1]
    used, local = np.unique(np.array(pstore.faces[a:b]), return_inverse=True)
    faces = np.ascontiguousarray(local.reshape(-1, 3), dtype=np.int64)
    return np.array(store.vertices[used]), faces, used, np.array(pstore.core[a:b])


def _unchecked_mesh(vertices: NDArray, faces: NDArray, **derived: Any):
    """A :class:`Mesh` over arrays the caller vouches for (a checked scan's, or a part of
    one), with ``derived`` values (search tree, face normals) already known: its fields set
    as :meth:`Mesh.with_name` shares a checked mesh's, without the check."""
    from meshfit.mesh import Mesh

    fields: dict[str, Any] = {"vertices": vertices, "faces": faces}
    fields |= {"vertex_colors": None, "name": "", "repairs": None, **derived}
    for a in (vertices, faces):
        if isinstance(a, np.ndarray) and a.flags.writeable:
            a.flags.writeable = False
    mesh = object.__new__(Mesh)
    for k, v in fields.items():
        object.__setattr__(mesh, k, v)
    return mesh


def _write_scan(mesh, folder: Path) -> Path:
    """Write the scan a map task searches (once per fit): its arrays, face normals and
    search tree as ``.npy`` files, which the workers memory-map."""
    if folder.is_dir():
        return folder
    tmp = folder.with_name(folder.name + ".part")
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir()
    tree = mesh.triangle_tree
    arrays = {"vertices": mesh.vertices, "faces": mesh.faces, "face_normals": mesh.face_normals}
    arrays |= {f"tree_{k}": getattr(tree, k) for k in tree._fields}
    for name, a in arrays.items():
        np.save(tmp / f"{name}.npy", np.ascontiguousarray(a))
    tmp.rename(folder)  # whole or absent: a task never reads a half-written scan
    return folder


#: per worker process: the scan last read (folder -> Mesh), shared by the tasks after it
_SCANS: dict[str, Any] = {}
_SCANS_LOCK = threading.Lock()


def _scan(folder: str):
    """The scan in ``folder`` as a :class:`Mesh` over memory-mapped read-only arrays, with
    the client's search tree and face normals; kept for the next task of the same fit.

    The mesh is not checked again (the client checked it; checking builds an edge table of
    the whole scan in every worker): its fields are set as :meth:`Mesh.with_name` shares a
    checked mesh's.
    """
    from meshfit.mesh.locate import TriangleTree

    with _SCANS_LOCK:
        if folder in _SCANS:
            return _SCANS[folder]
        base = Path(folder)

        def read(name: str) -> NDArray:
            return np.asarray(np.load(base / f"{name}.npy", mmap_mode="r"))

        tree = TriangleTree(*(read(f"tree_{k}") for k in TriangleTree._fields))
        mesh = _unchecked_mesh(
            read("vertices"), read("faces"), face_normals=read("face_normals"), triangle_tree=tree
        )
        _SCANS.clear()  # one fit's scan at a time
        _SCANS[folder] = mesh
        return mesh


def forget_scans() -> None:
    """Let go of the scans this process memory-mapped (run on every worker when a fit ends,
    so a long-lived worker keeps no mapping of a removed file)."""
    with _SCANS_LOCK:
        _SCANS.clear()
