"""Out-of-core preparation: a scan too large to hold whole, cut into patch files.

:func:`prepare_out_of_core` takes a mesh file to the per-patch submeshes the spring-mesh
tasks read (:func:`meshfit.pipeline.cluster.spring_file_task`), holding at any time one
chunk, one brick or one or two patches' pieces of the scan, besides the arrays of the
coarse proxy:

1. the file is read into a bricked, memory-mapped store (:func:`meshfit.mesh.store.write_store`);
2. a proxy is simplified from it brick by brick (:func:`meshfit.shrinkwrap.simplify_store`);
3. the proxy is laid out (:func:`meshfit.layout.auto.auto_layout`) and cut into patches;
4. the store's faces are sorted into those patches, with a halo
   (:func:`meshfit.layout.outofcore.assign_faces`);
5. the layout's corners and curves are carried to the scan, each curve once
   (:func:`meshfit.layout.outofcore.carry_network`);
6. each patch is cut from its piece along its carried sides
   (:func:`meshfit.layout.outofcore.cut_patch`) and written to ``cut/patch-<p>.npz``.

A scan's creases are not its proxy's (a coarse proxy folds sharply where the scan turns
smoothly, and the reverse): the proxy is laid out without creases unless asked.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

from meshfit import errors

__all__ = ["Prepared", "prepare_out_of_core"]


@dataclass(frozen=True, eq=False)
class Prepared:
    """Result of :func:`prepare_out_of_core`.

    Attributes
    ----------
    folder : Path
    store : MeshStore
        The scan, bricked (``folder / "mesh"``).
    proxy : Mesh
        The coarse proxy the layout was made on.
    layout : Layout
        The layout, on ``proxy``.
    patch_store : PatchStore
        The scan's faces by patch, with halos (``folder / "patches"``).
    network : CarriedNetwork
        The layout's corners and curves on the scan.
    patch_files : list of Path
        Each patch cut from the scan (``folder / "cut"``), in the layout's order: the
        ``.npz`` that :func:`meshfit.pipeline.cluster.spring_file_task` reads; face indices
        are the store's.
    seconds : dict
        Wall time of each step.
    """

    folder: Path
    store: object
    proxy: object
    layout: object
    patch_store: object
    network: object
    patch_files: list[Path]
    seconds: dict[str, float]


def prepare_out_of_core(
    source,
    folder: str | os.PathLike,
    *,
    layout_options=None,
    proxy_faces: int | None = None,
    workers: int | None = 1,
    progress: Callable[[str, int, int], None] | None = None,
) -> Prepared:
    """Prepare ``source`` for a patch-parallel fit without holding it whole.

    Parameters
    ----------
    source : path, Mesh or (vertices, faces)
        As :func:`meshfit.mesh.store.write_store` reads it.
    folder : path
        A new (or empty) folder for the store, the patch store and the patch files.
    layout_options : LayoutOptions, optional
        For the proxy's layout; default: the defaults without creases.
    proxy_faces : int, optional
        Faces of the proxy (default :data:`meshfit.layout.auto.PROXY_FACES`).
    workers : int or None
        Threads for the brick and patch steps (None: one per core).
    progress : callable(step, done, total), optional

    Returns
    -------
    Prepared

    Raises
    ------
    meshfit.errors.MeshfitError
        A bad file, a folder that is not new, or a layout whose patches cannot be cut from
        the scan (named).
    """
    from meshfit._threads import map_threads, n_workers
    from meshfit.layout.auto import PROXY_FACES, LayoutOptions, auto_layout
    from meshfit.layout.extract import extract_patches
    from meshfit.layout.outofcore import assign_faces, carry_network, cut_patch
    from meshfit.mesh.store import write_store
    from meshfit.pipeline.cluster import _patch_arrays
    from meshfit.pipeline.store import save_npz
    from meshfit.shrinkwrap.proxy import simplify_store

    root = Path(folder)
    if root.exists() and (not root.is_dir() or any(root.iterdir())):
        raise errors.InputError(f"{root}: exists and is not an empty folder")
    opts = layout_options or replace(LayoutOptions(), crease_angle=None)
    threads = n_workers(workers)
    seconds: dict[str, float] = {}

    def step(name: str):
        def tick(done: int, total: int) -> None:
            if progress is not None:
                progress(name, done, total)

        return tick

    t = time.perf_counter()
    store = write_store(source, root / "mesh", progress=step("store"))
    seconds["store"] = time.perf_counter() - t
    t = time.perf_counter()
    target = int(PROXY_FACES if proxy_faces is None else proxy_faces)
    proxy = simplify_store(store, min(target, store.n_faces), workers=threads).mesh
    seconds["proxy"] = time.perf_counter() - t
    t = time.perf_counter()
    layout = auto_layout(proxy, opts)
    cut_proxy = extract_patches(proxy, layout, workers=threads)
    seconds["layout"] = time.perf_counter() - t
    t = time.perf_counter()
    pstore = assign_faces(
        store, cut_proxy, root / "patches", workers=threads, progress=step("assign")
    )
    del cut_proxy
    seconds["assign"] = time.perf_counter() - t
    t = time.perf_counter()
    network = carry_network(store, pstore, proxy, layout)
    seconds["carry"] = time.perf_counter() - t
    t = time.perf_counter()
    (root / "cut").mkdir()

    def one(p: int) -> Path:
        patch = cut_patch(store, pstore, layout, network, p)
        return save_npz(root / "cut" / f"patch-{p}.npz", _patch_arrays(patch))

    n = int(layout.n_patches)
    files = map_threads(
        one,
        list(range(n)),
        threads,
        cost=[float(x) for x in pstore.patch_start[1:] - pstore.patch_start[:-1]],
        progress=step("cut"),
    )
    seconds["cut"] = time.perf_counter() - t
    return Prepared(root, store, proxy, layout, pstore, network, files, seconds)
