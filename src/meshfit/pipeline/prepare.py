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

__all__ = [
    "PREPARED_FORMAT",
    "PREPARED_VERSION",
    "Prepared",
    "open_prepared",
    "prepare_out_of_core",
]

#: the versioned JSON that marks a finished preparation (written last)
PREPARED_FORMAT = "meshfit-prepared"
PREPARED_VERSION = 1
PREPARED_META = "prepared.json"


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
    name : str
        The source's file name ("" for arrays).
    sha256 : str
        SHA-256 of the store's vertex and face arrays, as
        :func:`meshfit.pipeline.store.mesh_hash` takes a mesh's (the fit's content key).
    """

    folder: Path
    store: MeshStore
    proxy: Mesh
    layout: Layout
    patch_store: PatchStore
    network: CarriedNetwork
    patch_files: list[Path]
    seconds: dict[str, float]
    name: str = ""
    sha256: str = ""

    @property
    def bbox_diagonal(self) -> float:
        """The scan's bounding-box diagonal (of the store's vertices)."""
        import numpy as np

        return float(np.linalg.norm(self.store.bbox[1] - self.store.bbox[0]))

    def corner_xyz(self):
        """The layout's corners on the scan: ``(n_corners, 3) float64``."""
        c = self.network.corners
        x = self.store.vertices[self.store.faces[c.face]]
        return (x * c.bary[:, :, None]).sum(axis=1)


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
    name = Path(source).name if isinstance(source, (str, os.PathLike)) else ""
    name = name or str(getattr(source, "name", "") or "")
    res = Prepared(
        root, store, proxy, layout, pstore, network, files, seconds, name, _store_hash(store)
    )
    _save(res)
    return res


def _store_hash(store) -> str:
    """SHA-256 of the store's vertex and face arrays, read a chunk at a time."""
    import hashlib

    import numpy as np

    from meshfit.mesh.store import CHUNK_FACES

    h = hashlib.sha256()
    for a in (store.vertices, store.faces):
        for i in range(0, a.shape[0], CHUNK_FACES):
            chunk = np.ascontiguousarray(a[i : i + CHUNK_FACES], dtype=a.dtype.newbyteorder("<"))
            h.update(chunk.tobytes())
    return h.hexdigest()


def _save(res: Prepared) -> None:
    """What a fit reads besides the stores and the patch files: the proxy, its layout, the
    carried network, and last ``prepared.json`` (whose presence marks a finished
    preparation)."""
    import numpy as np

    from meshfit.layout import save_layout
    from meshfit.pipeline.store import save_npz, write_json

    root = res.folder
    save_npz(root / "proxy.npz", {"vertices": res.proxy.vertices, "faces": res.proxy.faces})
    save_layout(res.layout, root / "layout.json", mesh=res.proxy)
    net = {"corner_face": res.network.corners.face, "corner_bary": res.network.corners.bary}
    for k, c in enumerate(res.network.curves):
        net[f"curve_face_{k}"] = c.points.face
        net[f"curve_bary_{k}"] = c.points.bary
        net[f"curve_kind_{k}"] = np.array([c.kind])
    save_npz(root / "network.npz", net)
    write_json(
        root / PREPARED_META,
        {
            "format": PREPARED_FORMAT,
            "version": PREPARED_VERSION,
            "name": res.name,
            "sha256": res.sha256,
            "faces": res.store.n_faces,
            "vertices": res.store.n_vertices,
            "patches": len(res.patch_files),
            "curves": len(res.network.curves),
            "proxy_faces": int(res.proxy.n_faces),
            "seconds": {k: round(v, 3) for k, v in res.seconds.items()},
        },
    )


def is_prepared(path) -> bool:
    """Whether ``path`` is a folder :func:`prepare_out_of_core` finished."""
    return isinstance(path, (str, os.PathLike)) and (Path(path) / PREPARED_META).is_file()


def open_prepared(folder: str | os.PathLike) -> Prepared:
    """The preparation in ``folder`` (:func:`prepare_out_of_core`), its arrays memory-mapped.

    Raises
    ------
    meshfit.errors.InputError
        Not a finished preparation, another format or version, or files that disagree with
        ``prepared.json``.
    """
    import numpy as np

    from meshfit.layout import load_layout
    from meshfit.layout.outofcore import CarriedNetwork, open_patch_store
    from meshfit.mesh import Mesh
    from meshfit.mesh.store import open_store, read_meta
    from meshfit.pipeline.store import load_npz
    from meshfit.types import SurfaceCurve, SurfacePoints

    root = Path(folder)
    meta_path, meta = read_meta(
        root, PREPARED_META, PREPARED_FORMAT, PREPARED_VERSION, "prepared scan folder"
    )
    try:
        n, n_curves = int(meta["patches"]), int(meta["curves"])
        name, sha = str(meta["name"]), str(meta["sha256"])
        seconds = {str(k): float(v) for k, v in dict(meta["seconds"]).items()}
    except (KeyError, TypeError, ValueError) as exc:
        raise errors.InputError(f"{meta_path}: missing or malformed field ({exc})") from None
    store = open_store(root / "mesh")
    pstore = open_patch_store(root / "patches")
    try:
        z = load_npz(root / "proxy.npz")
        proxy = Mesh(z["vertices"], z["faces"], name=f"{name} proxy")
        layout = load_layout(root / "layout.json", proxy, check_topology=False)
        z = load_npz(root / "network.npz")
        corners = SurfacePoints(z["corner_face"], z["corner_bary"])
        kinds = [str(z[f"curve_kind_{k}"][0]) for k in range(n_curves)]
        if not set(kinds) <= {"boundary", "feature"}:
            raise ValueError("a curve kind other than boundary or feature")
        curves = [
            SurfaceCurve(
                SurfacePoints(z[f"curve_face_{k}"], z[f"curve_bary_{k}"]),
                False,
                "feature" if kinds[k] == "feature" else "boundary",
            )
            for k in range(n_curves)
        ]
    except (KeyError, OSError, ValueError) as exc:
        raise errors.InputError(f"{root}: a damaged preparation ({exc})") from None
    files = [root / "cut" / f"patch-{p}.npz" for p in range(n)]
    missing = [f for f in files if not f.is_file()]
    if missing:
        raise errors.InputError(f"{missing[0]}: missing from the prepared folder")
    if layout.n_patches != n or pstore.n_patches != n or len(layout.curves) != n_curves:
        raise errors.InputError(f"{meta_path}: the layout and the patch store disagree with it")
    for pts in (corners, *(c.points for c in curves)):
        if pts.face.size and (pts.face.min() < 0 or pts.face.max() >= store.n_faces):
            raise errors.InputError(f"{root / 'network.npz'}: a face index out of range")
    if corners.face.size != np.asarray(layout.corners.face).size:
        raise errors.InputError(f"{root / 'network.npz'}: not the layout's corners")
    network = CarriedNetwork(corners, curves)
    return Prepared(root, store, proxy, layout, pstore, network, files, seconds, name, sha)


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
