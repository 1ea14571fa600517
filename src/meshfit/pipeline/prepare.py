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
from typing import TYPE_CHECKING

from meshfit import errors

if TYPE_CHECKING:
    from meshfit.layout import Layout
    from meshfit.layout.outofcore import CarriedNetwork, PatchStore
    from meshfit.mesh import Mesh
    from meshfit.mesh.store import MeshStore

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
    store: MeshStore
    proxy: Mesh
    layout: Layout
    patch_store: PatchStore
    network: CarriedNetwork
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
    from meshfit.mesh.store import check_new_folder, write_store
    from meshfit.pipeline.cluster import _patch_arrays
    from meshfit.pipeline.store import save_npz
    from meshfit.shrinkwrap.proxy import simplify_store

    root = Path(folder)
    check_new_folder(root)
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
    proxy = simplify_store(
        store, min(target, store.n_faces), workers=threads, progress=step("proxy")
    ).mesh
    seconds["proxy"] = time.perf_counter() - t
    t = time.perf_counter()
    layout = auto_layout(proxy, opts)
    cut_proxy = extract_patches(proxy, layout, workers=threads)
    step("layout")(1, 1)
    seconds["layout"] = time.perf_counter() - t
    t = time.perf_counter()
    pstore = assign_faces(
        store, cut_proxy, root / "patches", workers=threads, progress=step("assign")
    )
    del cut_proxy
    seconds["assign"] = time.perf_counter() - t
    t = time.perf_counter()
    network = carry_network(store, pstore, proxy, layout)
    step("carry")(1, 1)
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


def add_commands(sub) -> None:
    """Add ``meshfit prepare MESH --out FOLDER`` to the CLI's sub-parsers."""
    from meshfit._cliargs import own_inputs

    p = sub.add_parser(
        "prepare",
        help="cut a scan too large to hold whole into patch files, out of core",
        description=(
            "Read the mesh into a bricked, memory-mapped store (a binary PLY of triangles is "
            "never read whole), simplify a proxy from it brick by brick, lay the proxy out, "
            "sort the scan's faces into its patches and cut each patch from the scan along "
            "the layout's curves carried over, one patch at a time. The folder then holds "
            "mesh/ (the store), patches/ (the faces by patch) and cut/patch-<p>.npz (what "
            "the spring-mesh tasks read)."
        ),
    )
    p.add_argument("mesh", help="mesh file (a binary .ply of triangles streams)")
    p.add_argument("--out", required=True, help="new or empty output folder")
    p.add_argument(
        "--proxy-faces",
        type=int,
        default=None,
        metavar="N",
        help="faces of the proxy the layout is made on (default: as the fit's)",
    )
    p.add_argument("--workers", type=int, default=None, help="threads (default: one per core)")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    own_inputs(p, ("mesh",), ("out",))
    p.set_defaults(func=cmd_prepare)


def cmd_prepare(args) -> int:
    """``meshfit prepare``: the summary of :func:`prepare_out_of_core`."""
    from meshfit._cliout import print_json, print_table
    from meshfit._malloc import peak_rss
    from meshfit._progress import stage_progress

    if args.proxy_faces is not None and args.proxy_faces < 20:
        raise errors.InputError(f"--proxy-faces must be >= 20, got {args.proxy_faces}")
    mesh = Path(args.mesh)
    if not mesh.is_file():
        raise errors.MeshFileError(f"{mesh}: no such file")
    with stage_progress(quiet=args.json) as show:
        res = prepare_out_of_core(
            mesh,
            args.out,
            proxy_faces=args.proxy_faces,
            workers=args.workers,
            progress=show,
        )
    rows = int(res.patch_store.faces.shape[0])
    peak = peak_rss()
    out = {
        "mesh": str(mesh),
        "folder": str(res.folder),
        "faces": res.store.n_faces,
        "dropped_faces": res.store.dropped_faces,
        "bricks": res.store.n_bricks,
        "proxy_faces": int(res.proxy.n_faces),
        "patches": len(res.patch_files),
        "patch_rows_per_face": round(rows / max(res.store.n_faces, 1), 3),
        "seconds": {k: round(v, 3) for k, v in res.seconds.items()},
        "peak_rss_mib": None if peak is None else round(peak / 2**20, 1),
    }
    if args.json:
        print_json(out)
    else:
        print_table(f"prepared {mesh.name}", out)
    return 0
