"""The whole fit from one call: layout -> cut -> spring meshes -> B-spline fit -> displacement
-> stitch -> exports -> errors -> report.

:func:`run_fit` wires the stages of the product together (``DESIGN.md``, "How the fit pipeline
flows"). Every stage's output is saved under ``<out>/stages/`` as ``.npz`` or JSON named by a
content hash of its inputs and options, so ``resume=True`` re-uses the stages already done;
patches are processed in parallel on threads between the cut and the stitch (the spring-mesh
and fitting kernels release the GIL); every file is written atomically; the summary
``summary.json`` holds per-stage timings, per-patch metrics and the error of the spline-only
and the displaced reconstructions against the input, as fractions of its bbox diagonal.

Stitching
---------
With either continuity the shared boundaries are made identical at the fitting step: every
layout curve gets one cubic B-spline curve, least-squares fitted to the spring-mesh side that
follows it (end points pinned to the layout corners), and every patch using the curve pins
its boundary row of control points to that curve's control points (Krishnamurthy 2000,
sec. 8.1.3: boundary constraints at the fitting step). Control counts are unified across
curves so that patches sharing a curve agree. ``continuity="g1"`` then makes the network G1
with :func:`meshfit.stitch.stitch_surfaces`, and ``"auto"`` (the default) does so across
every curve but those the layout marks as creases (:attr:`meshfit.layout.Layout.creases`),
which stay C0 (the surface is meant to break there); the seams of vector displacement maps are
closed with :func:`meshfit.stitch.stitch_displacements` (with ``map_shapes="matched"`` the
maps first take equal texel counts along shared curves, and the seams are crack-free at
every output resolution). The seams are measured either way (gap and normal jump across each
curve, and the displaced gap as exported and at any resolution, in ``summary["seams"]``).
"""

from __future__ import annotations

import hashlib
import importlib
import io
import json
import os
import sys
import threading
import time
import zipfile
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from meshfit import __version__, tol
from meshfit._atomic import atomic_write, write_bytes, write_text
from meshfit._kernels.geometry import label_corner_max
from meshfit._threads import map_threads, n_workers
from meshfit._words import plural
from meshfit.errors import InputError, LayoutError
from meshfit.mesh import Mesh
from meshfit.mesh.locate import grid_tree, triangle_distances

__all__ = [
    "FORMATS",
    "STAGES",
    "FitOptions",
    "load_fit",
    "mesh_hash",
    "patch_payload",
    "run_fit",
    "spring_patch",
    "spring_task",
]

#: pipeline stages in order (keys of the summary's ``stages``)
STAGES = (
    "validate",
    "layout",
    "cut",
    "springs",
    "fit",
    "displacement",
    "stitch",
    "exports",
    "errors",
    "report",
)
#: output formats of ``FitOptions.formats``
FORMATS = ("usd", "3dm", "iges", "step", "obj", "glb", "exr", "png")
#: version of the stage files and the summary
PIPELINE_FORMAT = 2

Progress = Callable[[str, int, int], None]


@dataclass(frozen=True)
class FitOptions:
    """Options of :func:`run_fit` (all have defaults).

    Attributes
    ----------
    controls : (int, int)
        Requested control resolution ``(mu, mv)`` per patch (default 16 x 16). A patch never
        gets more controls than its spring grid has points; with C0 stitching the counts along
        each shared curve are unified (the smallest wins).
    class_controls : mapping of int to int, or pairs
        Control counts of chosen equal-count classes, ``{class: count}`` (default none). The
        classes (patch directions linked by shared curves and opposite sides, which must
        share one count) are listed in ``summary["control_classes"]`` with their members and
        the largest count their spring grids allow; a count above that is capped (with a
        note). Stored as sorted ``(class, count)`` pairs.
    continuity : {"auto", "c0", "g1"}
        Continuity across shared boundaries (default ``"auto"``: G1 except across the
        layout's crease curves, which stay C0; see the module notes).
    formats : tuple of str
        Outputs among :data:`FORMATS` (default usd, obj, glb, exr, png).
    patches : int, optional
        Patch count asked of the automatic layout (``layout="auto"``).
    layout_shape : bool, optional
        ``shape`` of :func:`meshfit.layout.auto.auto_layout`: move the base vertices so that
        the quads are square on the surface (default None: above 60 patches).
    drop_components_below : float
        Drop the mesh's components below this share of its area before the layout
        (default 0: none; the notes name those below 1% either way).
    crease_angle : float, optional
        ``crease_angle`` of :func:`meshfit.layout.auto.auto_layout`: chains of edges
        sharper than this many degrees become patch boundaries, C0 with continuity
        ``"auto"`` (default 40; None: no creases).
    layout_seed : int
        ``seed`` of :func:`meshfit.layout.auto.auto_layout`: the rotation of the automatic
        layout's base mesh (default 0). Another rotation gives other patches where the
        summary's notes name slivers, tapered or bulging patches, or corners that turn back.
    spring_level : int, optional
        Final spring-mesh level (default: the level whose point count is closest to the
        patch's vertex count, :func:`meshfit.springs.resample_patch`).
    spring_max_points : int, optional
        Upper bound on a patch's final spring-mesh point count.
    spring_rescue : bool
        Make a patch's spring mesh again from an area-balanced map with light relaxation
        where the relaxed grid misses the patch by more than a grid spacing (default True;
        ``rescue`` of :func:`meshfit.springs.resample_patch`), and up to two levels finer
        where that still misses (without ``spring_level``): pleats, squeezed bulges and
        protrusions are sampled (nefertiti's automatic layout: displaced Hausdorff distance
        1.46% -> 0.40% of the bbox diagonal, patches 24 and 51 rescued; spot's: 2.5% ->
        0.45%, the grids of patches 31 and 34, a horn and an ear, two levels finer); where
        neither is kept, the relaxed grid's last level evened out along its grid lines in
        the planar map (nefertiti's centroid-cube test layout, its patch over neck,
        shoulders and base: 1.8% -> 0.35%).
    spring_follow_folds : bool
        ``follow_folds`` of :func:`meshfit.springs.resample_patch`: spring vectors across a
        fold of the surface follow the grid line, so the grids cross the curled rims of ears
        and horns (default False). With the rescue on it does not lower the displaced
        reconstruction's error: the grids it improves miss their patches by less than a
        grid spacing, so they are no longer rescued, and the rescued grids fit closer (G1,
        16 x 16 controls, Hausdorff distance: nefertiti_bust 0.33% -> 0.42%, nefertiti
        0.35% -> 0.39%, spot 0.60% -> 0.65%; nefertiti's largest corner-zone normal jump
        3.4 -> 1.7 degrees).
    map_kind : {"vector", "normal"}
        Displacement map kind (default ``"vector"``: exact reconstruction of the grid).
    map_shapes : {"native", "matched"}
        Resolution of the vector maps. ``"native"`` (default): each map at its spring
        grid's resolution; the displaced mesh is the spring mesh, and the seams are
        crack-free as tessellated at the maps' own resolutions (the exported meshes; thesis
        sec. 8.2). ``"matched"``: equal texel counts along every shared curve, the largest
        of each equal-count class (:func:`meshfit.stitch.match_map_shapes`), so the seams
        are crack-free at every output resolution, for a renderer that tessellates the
        maps at its own rate; it costs texels (1.5x on igea's automatic layout, 2.3x
        refined to 1.07M faces, 2.5x on nefertiti) and time in the later stages.
    workers : int, optional
        Threads for the per-patch stages (default: all cores).
    report : bool
        Write ``report.html`` with its images (default True).
    image_size : int
        Width and height of the report's renders, pixels (default 640).
    normal_errors : bool
        Also measure each patch's normal-distance fit error (eq. 6.2, a closest-point
        search per grid point; default False: the parametric error, eq. 6.1, only).
    """

    controls: tuple[int, int] = (16, 16)
    class_controls: Any = ()
    continuity: str = "auto"
    formats: tuple[str, ...] = ("usd", "obj", "glb", "exr", "png")
    patches: int | None = None
    layout_shape: bool | None = None
    layout_seed: int = 0
    crease_angle: float | None = 40.0
    drop_components_below: float = 0.0
    spring_level: int | None = None
    spring_max_points: int | None = None
    spring_rescue: bool = True
    spring_follow_folds: bool = False
    map_kind: str = "vector"
    map_shapes: str = "native"
    workers: int | None = None
    report: bool = True
    image_size: int = 640
    normal_errors: bool = False

    def __post_init__(self) -> None:
        try:
            mu, mv = (int(c) for c in self.controls)
        except (TypeError, ValueError):
            raise InputError(f"controls must be two integers, got {self.controls!r}") from None
        if mu < 4 or mv < 4:
            raise InputError(f"controls must be at least 4 x 4, got {mu} x {mv}")
        object.__setattr__(self, "controls", (mu, mv))
        object.__setattr__(self, "class_controls", _class_pairs(self.class_controls))
        if self.continuity not in ("auto", "c0", "g1"):
            raise InputError(f"continuity must be 'auto', 'c0' or 'g1', got {self.continuity!r}")
        fm = tuple(str(f).strip().lower() for f in self.formats if str(f).strip())
        bad = [f for f in fm if f not in FORMATS]
        if bad:
            raise InputError(f"unknown output format {bad[0]!r}: choose from {', '.join(FORMATS)}")
        if "step" in fm:
            from meshfit.export import step_available

            if not step_available():
                raise InputError(
                    "STEP output needs OpenCASCADE: pip install 'meshfit[cad]' (cadquery-ocp)"
                )
        object.__setattr__(self, "formats", fm)
        if self.map_kind not in ("vector", "normal"):
            raise InputError(f"map_kind must be 'vector' or 'normal', got {self.map_kind!r}")
        if self.map_shapes not in ("matched", "native"):
            raise InputError(f"map_shapes must be 'native' or 'matched', got {self.map_shapes!r}")
        if self.workers is not None:
            n_workers(self.workers)  # an integer >= 1, else InputError
        if self.patches is not None and int(self.patches) < 1:
            raise InputError(f"patches must be >= 1, got {self.patches}")
        if self.layout_shape not in (None, True, False):
            raise InputError(f"layout_shape must be True, False or None, got {self.layout_shape!r}")
        seed = self.layout_seed
        if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
            raise InputError(f"layout_seed must be a whole number >= 0, got {seed!r}")
        object.__setattr__(self, "layout_seed", int(seed))
        if not 0.0 <= float(self.drop_components_below) < 1.0:
            raise InputError(
                "drop_components_below must be a share of the area in [0, 1), got "
                f"{self.drop_components_below!r}"
            )
        object.__setattr__(self, "drop_components_below", float(self.drop_components_below))
        if self.crease_angle is not None:
            a = float(self.crease_angle)
            if not 0.0 < a < 180.0:
                raise InputError(f"crease_angle must be between 0 and 180 degrees, got {a}")
            object.__setattr__(self, "crease_angle", a)
        if int(self.image_size) < 16:
            raise InputError(f"image_size must be >= 16 pixels, got {self.image_size}")

    def key(self, *names: str) -> dict[str, Any]:
        d = asdict(self)
        return {k: d[k] for k in names}


def _class_pairs(value: Any) -> tuple[tuple[int, int], ...]:
    """``class_controls`` as sorted ``(class, count)`` pairs, validated."""
    items = value.items() if isinstance(value, Mapping) else value
    try:
        pairs = [(int(c), int(n)) for c, n in items]
    except (TypeError, ValueError):
        raise InputError(
            f"class_controls must map class indices to counts, got {value!r}"
        ) from None
    seen: set[int] = set()
    for c, n in pairs:
        if c < 0:
            raise InputError(f"class_controls: class {c} is negative")
        if n < 4:
            raise InputError(f"class_controls: class {c} needs at least 4 controls, got {n}")
        if c in seen:
            raise InputError(f"class_controls: class {c} is given twice")
        seen.add(c)
    return tuple(sorted(pairs))


# ---------------------------------------------------------------------------- small helpers
def mesh_hash(mesh: Mesh) -> str:
    """SHA-256 of a mesh's vertex and face arrays (the content key of every stage)."""
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(mesh.vertices, dtype="<f8").tobytes())
    h.update(np.ascontiguousarray(mesh.faces, dtype="<i8").tobytes())
    return h.hexdigest()


def _key(*parts: Any) -> str:
    text = json.dumps([PIPELINE_FORMAT, __version__, *parts], sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:20]


def _save_npz(path: Path, arrays: dict[str, NDArray]) -> Path:
    """A deterministic ``.npz`` (fixed zip timestamps), written atomically.

    The arrays are stored, not deflated: deflating them took about 2 s of a million-face
    fit.
    """

    def write(tmp: str) -> None:
        with zipfile.ZipFile(tmp, "w", compression=zipfile.ZIP_STORED) as zf:
            for name in sorted(arrays):
                buf = io.BytesIO()
                np.lib.format.write_array(buf, np.ascontiguousarray(arrays[name]))
                info = zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0))
                info.compress_type = zipfile.ZIP_STORED
                info.external_attr = 0o644 << 16
                zf.writestr(info, buf.getvalue())

    return atomic_write(path, write)


def _load_npz(path: Path) -> dict[str, NDArray]:
    with np.load(path, allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


def _as_bytes(data: Any) -> NDArray[np.uint8]:
    """JSON text as a uint8 array (stored in stage ``.npz`` files without pickling)."""
    return np.frombuffer(json.dumps(data, default=_json_default).encode(), dtype=np.uint8)


def _from_bytes(a: NDArray[np.uint8]) -> Any:
    return json.loads(np.asarray(a, dtype=np.uint8).tobytes().decode())


def _untimed(rows: list[dict]) -> list[dict]:
    """Rows without wall times: stage files hold only what the inputs determine (the same
    bytes on every run)."""
    return [{k: v for k, v in r.items() if k != "seconds"} for r in rows]


def _write_json(path: Path, data: Any) -> Path:
    return write_text(path, json.dumps(data, indent=2, default=_json_default) + "\n")


def _json_default(o: Any) -> Any:
    if isinstance(o, np.integer):
        return int(o)
    if isinstance(o, np.floating):
        return float(o)
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def _sha_file(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


class _Stages:
    """Stage bookkeeping: cache files, timings, progress."""

    def __init__(self, out: Path, resume: bool, progress: Progress | None) -> None:
        self.dir = out / "stages"
        self.dir.mkdir(parents=True, exist_ok=True)
        self.resume = resume
        self.progress = progress
        self.info: dict[str, dict[str, Any]] = {}

    def path(self, stage: str, key: str, suffix: str) -> Path:
        return self.dir / f"{stage}-{key}{suffix}"

    def cached(self, stage: str, key: str, suffix: str) -> Path | None:
        p = self.path(stage, key, suffix)
        return p if self.resume and p.is_file() else None

    def start(self, stage: str) -> float:
        return time.perf_counter()

    def done(self, stage: str, t0: float, *, cached: bool, **extra: Any) -> None:
        self.info[stage] = {
            "seconds": round(time.perf_counter() - t0, 4),
            "cached": bool(cached),
            **extra,
        }
        self.tick(stage, 1, 1)

    def tick(self, stage: str, done: int, total: int) -> None:
        if self.progress is not None:
            self.progress(stage, done, total)


def _parallel(
    fn,
    items: Sequence,
    workers: int,
    stage: str,
    st: _Stages,
    cost: Sequence[float] | None = None,
) -> list:
    """``[fn(x) for x in items]`` on threads (`meshfit._threads.map_threads`), results in
    order, progress per item under ``stage``."""
    st.tick(stage, 0, len(items))
    return map_threads(
        fn, items, workers, cost=cost, progress=lambda done, n: st.tick(stage, done, n)
    )


# ---------------------------------------------------------------------------- C0 boundaries
def _side_row(grid: NDArray[np.float64], s: int) -> NDArray[np.float64]:
    """Grid points along side ``s``, from corner ``s`` to corner ``s + 1``."""
    if s == 0:
        return grid[:, 0]
    if s == 1:
        return grid[-1, :]
    if s == 2:
        return grid[::-1, -1]
    return grid[0, ::-1]


def _control_classes(
    layout,
    shapes: list[tuple[int, int]],
    controls: tuple[int, int],
    chosen: tuple[tuple[int, int], ...] = (),
) -> tuple[list[tuple[int, int]], list[dict[str, Any]], list[str]]:
    """Control counts per patch direction, equal along every shared curve.

    Direction 0 (u) of patch p holds sides 0 and 2, direction 1 (v) sides 1 and 3; the
    directions sharing a curve form one class (union-find), numbered in order of first
    appearance (patch 0's u is class 0). A class gets the smallest requested count that fits
    every member's grid, or its count from ``chosen`` capped by the smallest member grid.

    Returns
    -------
    counts : list of (mu, mv) per patch
    classes : list of dict
        ``class``, ``controls``, ``max`` (smallest member grid size) and ``members`` (pairs
        ``[patch, "u" | "v"]``) per class.
    notes : list of str
        Chosen counts that were capped.
    """
    from meshfit._unionfind import DisjointSets

    n = len(shapes)
    sets = DisjointSets(2 * n)
    first: dict[int, int] = {}
    for p in range(n):
        for s in range(4):
            c = int(layout.patch_curves[p, s])
            node = 2 * p + (s % 2)
            if c in first:
                sets.union(first[c], node)
            else:
                first[c] = node
    labels = sets.labels()
    n_cls = max(labels) + 1 if labels else 0
    cap = [np.inf] * n_cls
    want = [np.inf] * n_cls
    asked = [np.inf] * n_cls  # the smallest global count of the class's directions
    members: list[list[list]] = [[] for _ in range(n_cls)]
    for p in range(n):
        for d in (0, 1):
            c = labels[2 * p + d]
            members[c].append([p, "uv"[d]])
            cap[c] = min(cap[c], shapes[p][d])
            asked[c] = min(asked[c], controls[d])
            want[c] = min(asked[c], cap[c])
    notes = []
    explicit = {int(c) for c, _ in chosen}
    capped = [c for c in range(n_cls) if cap[c] < asked[c] and c not in explicit]
    if capped:
        both = " x ".join(str(int(x)) for x in controls)
        used = sorted({int(cap[c]) for c in capped})
        span = f"{used[0]}" if len(used) == 1 else f"{used[0]} to {used[-1]}"
        notes.append(
            f"controls: {both} asked, {span} used in {len(capped)} of {n_cls} control classes "
            "(at most the smallest spring grid of the class; see control_classes)"
        )
    for c, m in chosen:
        if c >= n_cls:
            raise InputError(
                f"class_controls: class {c} does not exist (the layout's patches have "
                f"{n_cls} equal-count classes, 0..{n_cls - 1}; see summary['control_classes'])"
            )
        want[c] = min(m, cap[c])
        if m > cap[c]:
            notes.append(
                f"control class {c}: {m} controls asked, {int(cap[c])} used (the smallest "
                "spring grid of the class)"
            )
    count = [int(w) for w in want]
    classes = [
        {"class": c, "controls": count[c], "max": int(cap[c]), "members": members[c]}
        for c in range(n_cls)
    ]
    out = [(count[labels[2 * p]], count[labels[2 * p + 1]]) for p in range(n)]
    return out, classes, notes


def _fit_curve(
    samples: NDArray[np.float64], m: int, a: NDArray[np.float64], b: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Control points ``(m, 3)`` of a clamped cubic curve through ``samples`` (uniform
    parameters), least squares with the end points pinned to ``a`` and ``b``."""
    from meshfit.bspline import basis_matrix, clamped_knots

    t = np.linspace(0.0, 1.0, samples.shape[0])
    B = basis_matrix(t, clamped_knots(m))
    rhs = samples - np.outer(B[:, 0], a) - np.outer(B[:, -1], b)
    inner, *_ = np.linalg.lstsq(B[:, 1:-1], rhs, rcond=None)
    return np.vstack([a[None], inner, b[None]])


def _boundary_pins(layout, corner_xyz, grids, counts) -> list[dict[str, NDArray]]:
    """Pinned boundary control rows of every patch (``fit_bspline``'s ``pin_boundary``)."""
    curve_ctrl: dict[int, NDArray[np.float64]] = {}
    ends = layout.curve_ends
    for p, grid in enumerate(grids):
        for s in range(4):
            c = int(layout.patch_curves[p, s])
            if c in curve_ctrl:
                continue
            row = _side_row(grid, s)
            if bool(layout.patch_reversed[p, s]):
                row = row[::-1]
            m = counts[p][s % 2]
            a, b = corner_xyz[int(ends[c, 0])], corner_xyz[int(ends[c, 1])]
            curve_ctrl[c] = _fit_curve(row, m, a, b)
    pins = []
    for p in range(len(grids)):
        sides = []
        for s in range(4):
            c = int(layout.patch_curves[p, s])
            ctrl = curve_ctrl[c]
            if bool(layout.patch_reversed[p, s]):
                ctrl = ctrl[::-1]
            sides.append(ctrl)
        # side rows run corner s -> s + 1; pin rows run in increasing parameter
        pins.append(
            {
                "v0": sides[0],
                "u1": sides[1],
                "v1": sides[2][::-1].copy(),
                "u0": sides[3][::-1].copy(),
            }
        )
    return pins


def _seam_metrics(layout, surfaces, grids_displaced, diag: float, samples: int = 33) -> dict:
    """Gap and normal jump across every curve shared by two patches (the normal jumps over
    smooth curves; those over the layout's crease curves, where the surface is meant to
    break, apart as ``crease_normal_jump_max_deg``)."""
    t = np.linspace(0.0, 1.0, samples)
    users: dict[int, list[tuple[int, int, bool]]] = {}
    for p in range(len(surfaces)):
        for s in range(4):
            users.setdefault(int(layout.patch_curves[p, s]), []).append(
                (p, s, bool(layout.patch_reversed[p, s]))
            )

    def side_params(s: int, along: NDArray[np.float64]):
        if s == 0:
            return along, np.zeros_like(along)
        if s == 1:
            return np.ones_like(along), along
        if s == 2:
            return 1.0 - along, np.ones_like(along)
        return np.zeros_like(along), 1.0 - along

    gap = 0.0
    angle = 0.0
    angle_inner = 0.0
    angle_ends = 0.0
    disp_gap = 0.0
    disp_any = 0.0
    shared = 0
    crease_angle = 0.0
    n_crease = 0
    for curve, uses in users.items():
        if len(uses) != 2:
            continue
        shared += 1
        on_crease = bool(layout.creases[curve])
        pts, nrm = [], []
        for p, s, rev in uses:
            along = t[::-1] if rev else t  # both in the curve's own direction
            u, v = side_params(s, along)
            S, _, _, N = surfaces[p].points_and_frames(u, v)
            pts.append(S)
            nrm.append(N)
        gap = max(gap, float(np.linalg.norm(pts[0] - pts[1], axis=1).max()))
        cos = np.clip((nrm[0] * nrm[1]).sum(axis=1), -1.0, 1.0)
        a = np.degrees(np.arccos(cos))
        if on_crease:
            n_crease += 1
            crease_angle = max(crease_angle, float(a.max()))
            a = np.zeros_like(a)
        angle = max(angle, float(a.max()))
        angle_ends = max(angle_ends, float(a[0]), float(a[-1]))
        p0, s0, _ = uses[0]
        m = surfaces[p0].shape[0 if s0 % 2 == 0 else 1]
        span = 1.0 / max(m - 3, 1)  # one knot span: the corner zone
        inner = (t > span) & (t < 1.0 - span)
        if inner.any():
            angle_inner = max(angle_inner, float(a[inner].max()))
        rows, cont = [], []
        for (p, s, rev), spline_pts in zip(uses, pts, strict=True):
            row = _side_row(grids_displaced[p], s)
            row = row[::-1] if rev else row
            rows.append(row)
            # at any output resolution: the spline plus the boundary texels' model-space
            # vectors read linearly at the curve parameters t
            tex = np.linspace(0.0, 1.0, len(row))
            u, v = side_params(s, tex[::-1] if rev else tex)
            vec = row - surfaces[p].evaluate(u, v)
            cont.append(spline_pts + np.stack([np.interp(t, tex, vec[:, c]) for c in range(3)], 1))
        # displaced boundaries: distance of each row's points to the other row's polyline
        disp_gap = max(disp_gap, _polyline_gap(rows[0], rows[1]), _polyline_gap(rows[1], rows[0]))
        disp_any = max(disp_any, float(np.linalg.norm(cont[0] - cont[1], axis=1).max()))
    return {
        "shared_curves": shared,
        "spline_gap_max": gap / diag,
        "spline_normal_jump_max_deg": angle,
        "spline_normal_jump_inner_max_deg": angle_inner,
        "spline_normal_jump_corner_point_max_deg": angle_ends,
        "crease_curves": n_crease,
        "crease_normal_jump_max_deg": crease_angle,
        "displaced_gap_max": disp_gap / diag,
        "displaced_gap_any_resolution_max": disp_any / diag,
    }


def _polyline_gap(a: NDArray[np.float64], b: NDArray[np.float64]) -> float:
    """Largest distance from the points ``a`` to the polyline ``b``."""
    from meshfit._kernels.geometry import polyline_gap

    return float(polyline_gap(np.ascontiguousarray(a), np.ascontiguousarray(b)))


# ---------------------------------------------------------------------------- errors
def _surface_distance(
    mesh: Mesh, V: NDArray[np.float64], F: NDArray[np.int64], tree, known=None
) -> tuple[NDArray, NDArray]:
    """Two-sided distances: reconstruction vertices to the input, input vertices to the
    reconstruction (a triangle soup ``V, F`` and its tree). ``known`` (per vertex of ``V``,
    optional): an upper bound of each one's distance to the input; where it is below
    ``tol.KNOWN_DISTANCE`` of the diagonal it is the distance (no search)."""
    todo = np.arange(V.shape[0])
    to_input = np.zeros(V.shape[0])
    if known is not None:
        near = known <= tol.KNOWN_DISTANCE * mesh.bbox_diagonal
        to_input[near] = known[near]
        todo = np.flatnonzero(~near)
    if todo.size:
        to_input[todo], _ = triangle_distances(
            V[todo], mesh.vertices, mesh.faces, tree=mesh.triangle_tree
        )
    from_input, _ = triangle_distances(mesh.vertices, V, F, tree=tree)
    return to_input, from_input


def _error_figures(
    mesh: Mesh, V, F, tree, known=None
) -> tuple[dict[str, float], NDArray[np.float64], NDArray[np.float64]]:
    """Error figures over the bbox diagonal, each reconstruction vertex's distance to the
    input and each input vertex's distance to the reconstruction (``known``: see
    `_surface_distance`)."""
    a, b = _surface_distance(mesh, V, F, tree, known)
    diag = mesh.bbox_diagonal
    both = np.concatenate([a, b])
    return (
        {
            "rms": float(np.sqrt(np.mean(both**2)) / diag),
            "hausdorff": float(both.max() / diag),
            "mean": float(both.mean() / diag),
            "to_input_max": float(a.max() / diag),
            "from_input_max": float(b.max() / diag),
        },
        a,
        b,
    )


def _texel_grids(surfaces: list, shapes: list[tuple[int, ...]]) -> list[NDArray[np.float64]]:
    """Each spline at its map's texels (``shapes[p]`` starts with the map's rows and
    columns), as the displaced grids are laid out."""
    return [
        s.evaluate_grid(np.linspace(0.0, 1.0, sh[0]), np.linspace(0.0, 1.0, sh[1]))
        for s, sh in zip(surfaces, shapes, strict=True)
    ]


def _spline_errors(mesh: Mesh, grids: list[NDArray[np.float64]]):
    """Error figures of the spline grids (`_texel_grids`) against the input, and each grid
    vertex's distance to the input."""
    V, F = _soup(grids)
    fig, to_input, _ = _error_figures(mesh, V, F, grid_tree(V, F, [g.shape[:2] for g in grids]))
    return fig, to_input


def _early_spline(mesh: Mesh, surfaces: list, shapes: list[tuple[int, ...]]):
    """The spline grids at the maps' texels (``shapes``) and `_spline_errors` of them."""
    grids = _texel_grids(surfaces, shapes)
    return (grids, *_spline_errors(mesh, grids))


def _spring_bounds(
    displaced: list[NDArray[np.float64]], grids: list[NDArray[np.float64]]
) -> NDArray[np.float64]:
    """Upper bounds of the displaced grids' vertices' distances to the input (stacked as
    `_soup` stacks them): a map with its spring grid's shape puts each texel where it
    reproduces that grid's point, which lies on the input (inf for other shapes)."""
    out = []
    for D, G in zip(displaced, grids, strict=True):
        if D.shape == G.shape:
            out.append(np.linalg.norm(D - G, axis=2).reshape(-1))
        else:
            out.append(np.full(D.shape[0] * D.shape[1], np.inf))
    return np.concatenate(out) if out else np.zeros(0)


def _per_patch_max(
    mesh: Mesh, face_patch: NDArray[np.int64] | None, value: NDArray, n: int
) -> list[float]:
    """Largest ``value`` (one per input vertex) over each patch's input vertices (a vertex on
    a patch boundary counts for every patch of its faces); None without the face labels."""
    if face_patch is None or len(face_patch) != mesh.n_faces:
        return [None] * n
    worst = label_corner_max(
        np.ascontiguousarray(mesh.faces, dtype=np.int64),
        np.ascontiguousarray(face_patch, dtype=np.int64),
        np.ascontiguousarray(value, dtype=np.float64),
        int(n),
    )
    return np.maximum(worst, 0.0).tolist()


def _soup(arrays: list[NDArray[np.float64]]) -> tuple[NDArray, NDArray]:
    from meshfit.springs import grid_triangles

    Vs, Fs, base = [], [], 0
    for X in arrays:
        nu, nv = X.shape[:2]
        Vs.append(X.reshape(-1, 3))
        Fs.append(grid_triangles(nu, nv) + base)
        base += nu * nv
    return np.vstack(Vs), np.vstack(Fs)


# ---------------------------------------------------------------------------- the run
#: modules the exporters of a format import (loaded on a side thread while the fit runs: the
#: USD ones take about half a second)
_EXPORT_MODULES = {
    "usd": ("pxr.Gf", "pxr.Sdf", "pxr.Usd", "pxr.UsdGeom", "pxr.Vt"),
    "3dm": ("rhino3dm",),
}


def _prefetch_exporters(formats) -> None:
    """Import the modules of the exporters in ``formats`` on a thread of their own (an
    import error is left for the exports stage to report).

    Not a daemon thread: a fit that fails early (a mesh the automatic layout cannot cut)
    must not exit while the thread is inside an extension's import (USD's), which aborts
    the process ("terminate called without an active exception", exit code 134 instead of
    the error's 2); the interpreter waits for the import to finish instead."""
    names = [m for f in formats for m in _EXPORT_MODULES.get(f, ())]
    if not names or all(n in sys.modules for n in names):
        return

    def load() -> None:
        for name in names:
            try:
                importlib.import_module(name)
            except ImportError:
                return

    threading.Thread(target=load, name="meshfit-prefetch", daemon=False).start()


#: components below this share of the area are named in the notes
SMALL_COMPONENT = 0.01


def _small_components(mesh: Mesh, drop_below: float, notes: list[str]) -> Mesh:
    """The mesh, without its components below ``drop_below`` of the area when that is above
    0; components below `SMALL_COMPONENT` are named in ``notes`` either way."""
    from meshfit.mesh.components import component_shares, drop_small_components

    if mesh.n_components < 2:
        return mesh
    shares = component_shares(mesh)
    small = np.flatnonzero(shares < max(SMALL_COMPONENT, drop_below))
    if small.size == 0:
        return mesh
    worst = ", ".join(f"{100 * shares[c]:.2g}%" for c in small[np.argsort(shares[small])][:5])
    if drop_below > 0.0:
        mesh, _ = drop_small_components(mesh, drop_below)
        notes.append(
            f"dropped {plural(small.size, 'component')} below {100 * drop_below:.3g}% of the "
            f"area ({worst}; FitOptions.drop_components_below, --drop-components)"
        )
    else:
        notes.append(
            f"{plural(small.size, 'component')} below {100 * SMALL_COMPONENT:.3g}% of the area "
            f"({worst}), each laid out and fitted on its own: --drop-components SHARE "
            "(FitOptions.drop_components_below) drops them"
        )
    return mesh


def _resolve_layout(mesh: Mesh, layout, options: FitOptions, layout_report: list | None = None):
    """(layout source key, loader) for a Layout, a path, ``"auto"`` or None; the automatic
    layout appends what it did to ``layout_report``."""
    from meshfit.layout import Layout, layout_to_json, load_layout

    if isinstance(layout, Layout):
        text = layout_to_json(layout)
        return hashlib.sha256(text.encode()).hexdigest(), lambda: layout
    if layout is None or (isinstance(layout, str) and layout == "auto"):
        from meshfit.layout.auto import AUTO_LAYOUT_REVISION

        def make():
            from meshfit.layout.auto import auto_layout

            return auto_layout(
                mesh,
                patches=options.patches,
                shape=options.layout_shape,
                seed=options.layout_seed,
                crease_angle=options.crease_angle,
                report=layout_report,
            )

        shape = {None: "", True: ":shaped", False: ":unshaped"}[options.layout_shape]
        seed = f":seed{options.layout_seed}" if options.layout_seed else ""
        crease = "" if options.crease_angle == 40.0 else f":crease{options.crease_angle}"
        return f"auto:{options.patches}{shape}{seed}{crease}:r{AUTO_LAYOUT_REVISION}", make
    if not isinstance(layout, (str, os.PathLike)):
        raise InputError(
            f"layout must be a Layout, a layout file's path, 'auto' or None, got "
            f"{type(layout).__name__}"
        )
    path = Path(layout)
    if not path.is_file():
        raise LayoutError(f"{path}: no such layout file")
    digest = hashlib.sha256(path.read_bytes()).hexdigest()
    return digest, lambda: load_layout(path, mesh)


def run_fit(
    mesh: Mesh | str | os.PathLike,
    out: str | os.PathLike,
    *,
    layout=None,
    options: FitOptions | None = None,
    resume: bool = False,
    progress: Progress | None = None,
    patch_map: Callable | None = None,
) -> dict[str, Any]:
    """Fit B-spline patches with displacement maps to a mesh and write every output.

    Parameters
    ----------
    mesh : Mesh or path
        The input; a path is loaded (and validated) with :func:`meshfit.load_mesh`.
    out : path
        Output folder (created): ``layout.json``, ``summary.json``, the exports, the report
        and ``stages/`` (the cache of every stage).
    layout : Layout, path, ``"auto"`` or None, keyword-only
        The patch layout: an object, a layout file, or the automatic layout for a closed
        genus-0 mesh (``"auto"``, also the default).
    options : FitOptions, keyword-only, optional
        Default ``FitOptions()``.
    resume : bool, keyword-only
        Re-use stage files in ``out/stages`` whose content hash matches (default False:
        everything is recomputed and the stage files are overwritten).
    progress : callable(stage, done, total), keyword-only, optional
        Called as each stage advances.
    patch_map : callable(fn, items) -> list, keyword-only, optional
        Runs the spring-mesh stage's per-patch tasks elsewhere (e.g. as Dask tasks, see
        :mod:`meshfit.batch`): called with :func:`spring_task` and one picklable
        ``(payload, options)`` pair per patch, returns the results in order. Default: threads.

    Returns
    -------
    dict
        The summary also written to ``out/summary.json``: ``stages`` (seconds, cached),
        ``patches`` (per-patch metrics), ``errors`` (``spline_only`` and ``displaced``:
        two-sided RMS and Hausdorff distance to the input over its bbox diagonal),
        ``seams``, ``outputs``.

    Raises
    ------
    meshfit.errors.MeshfitError
        Bad input (mesh, layout, options).

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 1.3 (the fitting pipeline), ch. 5 (spring meshes), ch. 6
       (B-spline fitting), ch. 7 (displacement maps), sec. 8.1 (continuity).
    """
    from meshfit.bspline import BSplineSurface, fit_bspline, fit_errors
    from meshfit.displacement import DisplacementMap, displacement_map, reconstruct
    from meshfit.layout import extract_patches, save_layout

    options = options or FitOptions()
    _prefetch_exporters(options.formats)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    st = _Stages(out, resume, progress)
    notes: list[str] = []
    workers = n_workers(options.workers)
    t_all = time.perf_counter()

    # ---- validate
    t0 = st.start("validate")
    if not isinstance(mesh, Mesh):
        from meshfit.mesh import load_mesh

        mesh = load_mesh(mesh, repair=True)
    if mesh.repairs is not None and mesh.repairs.changed():
        notes.append(f"the input was {mesh.repairs.summary()}")
    mesh = _small_components(mesh, options.drop_components_below, notes)
    # the content hash (hashlib releases the GIL) is taken on a thread while a layout is
    # made; a resumed run waits for it first, to look for a finished layout
    hasher = ThreadPoolExecutor(max_workers=1)
    hashed = hasher.submit(mesh_hash, mesh)
    hasher.shutdown(wait=False)
    diag = float(mesh.bbox_diagonal)
    st.done("validate", t0, cached=False)

    # ---- layout
    t0 = st.start("layout")
    layout_report: list = []
    source, make_layout = _resolve_layout(mesh, layout, options, layout_report)
    cached = None
    if resume:
        mhash = hashed.result()
        k_layout = _key("layout", mhash, source)
        cached = st.cached("layout", k_layout, ".json")
    if cached is not None:
        from meshfit.layout import load_layout

        lay = load_layout(cached, mesh, check_topology=False)
        write_bytes(out / "layout.json", cached.read_bytes())
    else:
        lay = make_layout()
        mhash = hashed.result()
        k_layout = _key("layout", mhash, source)
        staged = save_layout(lay, st.path("layout", k_layout, ".json"), mesh=mesh)
        write_bytes(out / "layout.json", staged.read_bytes())
    n_patches = int(lay.n_patches)
    route = None  # the automatic layout's route, where it was made (not cached)
    if source.startswith("auto"):
        from meshfit.layout.auto import auto_route

        route = (
            layout_report[0]["route"]
            if layout_report
            else auto_route(mesh, patches=options.patches, crease_angle=options.crease_angle)
        )
    if source.startswith("auto") and options.patches is not None and n_patches != options.patches:
        from meshfit.layout.auto import MIN_PATCHES

        why = (
            f"it makes three per base triangle, an even number of triangles, at least "
            f"{MIN_PATCHES} patches"
            if route == "sphere"
            else "it makes one per side of every cell, and more cells where a cell is not a "
            "disk or turns too far for one patch (meshfit.layout.regions)"
        )
        notes.append(
            f"the automatic layout has {n_patches} patches for the {options.patches} asked: {why}"
        )
    st.done("layout", t0, cached=cached is not None, patches=n_patches)

    # ---- cut (only run when a later stage needs the patches)
    k_cut = _key("cut", k_layout)
    patches_cache: list = []

    def patches():
        if not patches_cache:
            t = time.perf_counter()
            ps = extract_patches(mesh, lay, workers=workers)
            face_patch = np.full(mesh.n_faces, -1, dtype=np.int64)
            for p in ps:
                face_patch[p.face_parent] = p.index
            _save_npz(
                st.path("cut", k_cut, ".npz"),
                {
                    "face_patch": face_patch,
                    "n_faces": np.array([p.mesh.n_faces for p in ps], dtype=np.int64),
                    "n_vertices": np.array([p.mesh.n_vertices for p in ps], dtype=np.int64),
                },
            )
            patches_cache.append(ps)
            st.info["cut"] = {"seconds": round(time.perf_counter() - t, 4), "cached": False}
            st.tick("cut", 1, 1)
        return patches_cache[0]

    # ---- springs
    t0 = st.start("springs")
    spring_opts = options.key(
        "spring_level", "spring_max_points", "spring_rescue", "spring_follow_folds"
    )
    k_springs = _key("springs", k_cut, spring_opts)
    cached = st.cached("springs", k_springs, ".npz")
    if cached is not None:
        z = _load_npz(cached)
        grids = [z[f"grid_{p}"] for p in range(n_patches)]
        spring_info = _from_bytes(z["info"])
    else:
        ps = patches()
        t0 = st.start("springs")
        spring_kw = {
            "level": options.spring_level,
            "max_points": options.spring_max_points,
            "rescue": bool(options.spring_rescue),
            "follow_folds": bool(options.spring_follow_folds),
        }
        if patch_map is not None:
            res = patch_map(spring_task, [(patch_payload(p), spring_kw) for p in ps])
        else:
            res = _parallel(
                lambda p: spring_patch(p, **spring_kw),
                ps,
                workers,
                "springs",
                st,
                cost=[p.mesh.n_faces for p in ps],
            )
        grids = [g for g, _ in res]
        spring_info = [i for _, i in res]
        arrays = {f"grid_{p}": g for p, g in enumerate(grids)}
        arrays["info"] = _as_bytes(_untimed(spring_info))
        _save_npz(st.path("springs", k_springs, ".npz"), arrays)
    if "cut" not in st.info:
        st.info["cut"] = {"seconds": 0.0, "cached": True}
        st.tick("cut", 1, 1)
    st.done("springs", t0, cached=cached is not None, patch_tasks=patch_map is not None)

    # ---- fit (with the C0 boundary pins)
    t0 = st.start("fit")
    fit_opts = options.key("controls", "class_controls", "continuity", "normal_errors")
    k_fit = _key("fit", k_springs, fit_opts)
    cached = st.cached("fit", k_fit, ".npz")
    corner_xyz = mesh.xyz(lay.corners)
    counts, control_classes, class_notes = _control_classes(
        lay, [g.shape[:2] for g in grids], options.controls, options.class_controls
    )
    notes.extend(class_notes)
    if cached is not None:
        z = _load_npz(cached)
        surfaces = [BSplineSurface(z[f"ctrl_{p}"]) for p in range(n_patches)]
        fit_info = _from_bytes(z["info"])
    else:
        pins = _boundary_pins(lay, corner_xyz, grids, counts)

        def fit(p):
            t = time.perf_counter()
            s = fit_bspline(grids[p], controls=counts[p], pin_boundary=pins[p])
            if options.normal_errors:
                e = fit_errors(s, grids[p]).as_dict()
            else:  # parametric error only (eq. 6.1): the closest-point search is costly
                nu, nv = grids[p].shape[:2]
                S = s.evaluate_grid(np.linspace(0.0, 1.0, nu), np.linspace(0.0, 1.0, nv))
                par = np.linalg.norm(grids[p] - S, axis=2)
                e = {
                    "parametric_rms": float(np.sqrt(np.mean(par**2))),
                    "parametric_max": float(par.max()),
                }
            return s, {
                "controls": list(counts[p]),
                **{f"fit_{k}": v / diag for k, v in e.items()},
                "seconds": round(time.perf_counter() - t, 4),
            }

        res = _parallel(fit, list(range(n_patches)), workers, "fit", st)
        surfaces = [s for s, _ in res]
        fit_info = [i for _, i in res]
        if options.continuity in ("g1", "auto"):
            creases = lay.creases if options.continuity == "auto" else None
            surfaces = _stitch_g1(surfaces, notes, lay, creases)
        arrays = {f"ctrl_{p}": s.control_points for p, s in enumerate(surfaces)}
        arrays["info"] = _as_bytes(_untimed(fit_info))
        _save_npz(st.path("fit", k_fit, ".npz"), arrays)
    st.done("fit", t0, cached=cached is not None)

    # the spline-only surface needs the fit and the maps' rows and columns alone, which the
    # displacement and the stitch keep ("native" shapes: the spring grids'): its errors are
    # measured on a thread while the maps are made and the seams stitched, and the exports
    # are written on another while the displaced surface's errors are measured
    k_disp = _key("displacement", k_fit, options.map_kind)
    k_stitch = _key("stitch", k_disp, options.map_shapes)
    k_err = _key("errors", k_stitch, mhash)
    background = ThreadPoolExecutor(max_workers=2)
    early = None
    early_shapes = [g.shape[:2] for g in grids]
    if options.map_shapes == "native" and st.cached("errors", k_err, ".json") is None:
        early = background.submit(_early_spline, mesh, surfaces, early_shapes)

    def early_spline():
        """`_early_spline`'s result, if it was started and the maps have its shapes."""
        if early is not None and early_shapes == [d.shape[:2] for d in dmaps]:
            return early.result()
        return None

    # ---- displacement
    t0 = st.start("displacement")
    cached = st.cached("displacement", k_disp, ".npz")
    if cached is not None:
        z = _load_npz(cached)
        dmaps = [DisplacementMap(z[f"map_{p}"], options.map_kind) for p in range(n_patches)]
    else:
        dmaps = _parallel(
            lambda p: displacement_map(surfaces[p], grids[p], kind=options.map_kind),
            list(range(n_patches)),
            workers,
            "displacement",
            st,
        )
        _save_npz(
            st.path("displacement", k_disp, ".npz"),
            {f"map_{p}": d.values for p, d in enumerate(dmaps)},
        )
    st.done("displacement", t0, cached=cached is not None)

    # ---- stitch: C0 is built into the fit (pinned boundaries), G1 by meshfit.stitch; here
    # the displacement seams are closed and the seams measured
    t0 = st.start("stitch")
    cached = st.cached("stitch", k_stitch, ".npz")
    if cached is not None:
        z = _load_npz(cached)
        dmaps = [DisplacementMap(z[f"map_{p}"], options.map_kind) for p in range(n_patches)]
        seams = _from_bytes(z["seams"])
    else:
        if options.map_kind == "vector":
            dmaps = _stitch_maps(lay, surfaces, dmaps, notes, options.map_shapes == "matched")

    @cache
    def displaced_grids() -> list[NDArray[np.float64]]:
        return [reconstruct(surfaces[p], dmaps[p]) for p in range(n_patches)]

    @cache
    def face_patch() -> NDArray[np.int64] | None:
        """Patch of every input face (errors and report), read once."""
        return _face_patch(st, k_cut)

    @cache
    def spline_grids() -> list[NDArray[np.float64]]:
        """Each spline at its map's texels, as the displaced grids (errors and report)."""
        done = early_spline()
        return done[0] if done is not None else _texel_grids(surfaces, [d.shape for d in dmaps])

    if cached is None:
        seams = _seam_metrics(lay, surfaces, displaced_grids(), diag)
        seams["continuity"] = options.continuity
        arrays = {f"map_{p}": d.values for p, d in enumerate(dmaps)}
        arrays["seams"] = _as_bytes(seams)
        _save_npz(st.path("stitch", k_stitch, ".npz"), arrays)
    st.done("stitch", t0, cached=cached is not None)

    # ---- errors against the input
    def _errors_stage() -> tuple[dict[str, Any], list]:
        t0 = st.start("errors")
        cached = st.cached("errors", k_err, ".json")
        spline_distance: list = []
        if cached is not None:
            errors = json.loads(cached.read_text())
            dist_file = st.path("errors", k_err, ".npz")
            if dist_file.is_file():
                spline_distance.append(_load_npz(dist_file)["spline_to_input"])
        else:
            # the displaced surface's tree is built (serial work) while the spline-only
            # surface's searches may still run
            Vd, Fd = _soup(displaced_grids())
            tree = grid_tree(Vd, Fd, [g.shape[:2] for g in displaced_grids()])
            done = early_spline()
            spline_fig, spline_to_input = (
                done[1:] if done is not None else _spline_errors(mesh, spline_grids())
            )
            disp_fig, _, from_input = _error_figures(
                mesh, Vd, Fd, tree, _spring_bounds(displaced_grids(), grids)
            )
            errors = {
                "spline_only": spline_fig,
                "displaced": disp_fig,
                "units": "fraction of the input's bbox diagonal",
                # per patch: its input vertices' largest distance to the displaced surface
                "displaced_from_input_max_per_patch": [
                    None if v is None else v / diag
                    for v in _per_patch_max(mesh, face_patch(), from_input, n_patches)
                ],
            }
            spline_distance.append(spline_to_input)
            _save_npz(st.path("errors", k_err, ".npz"), {"spline_to_input": spline_to_input})
            _write_json(st.path("errors", k_err, ".json"), errors)
        st.done("errors", t0, cached=cached is not None)
        return errors, spline_distance

    # ---- exports, on a thread of their own: writing files is mostly serial work, which the
    # errors stage's parallel searches hide (their seconds overlap in the summary)
    def exports() -> dict[str, list[str]]:
        t0 = st.start("exports")
        names = [f"patch_{p:03d}" for p in range(n_patches)]
        k_exp = _key("exports", k_stitch, options.formats)
        cached = st.cached("exports", k_exp, ".json")
        outputs: dict[str, list[str]] = {}
        if cached is not None:
            record = json.loads(cached.read_text())
            ok = all(
                (out / f).is_file() and _sha_file(out / f) == h for f, h in record["sha256"].items()
            )
            if ok:
                outputs = record["outputs"]
            else:
                cached = None
        if cached is None:
            outputs = _write_exports(out, names, surfaces, dmaps, options.formats, st)
            files = [f for fs in outputs.values() for f in fs]
            _write_json(
                st.path("exports", k_exp, ".json"),
                {"outputs": outputs, "sha256": {f: _sha_file(out / f) for f in files}},
            )
        st.done("exports", t0, cached=cached is not None)
        return outputs

    exported = background.submit(exports)
    try:
        errors, spline_distance = _errors_stage()
    finally:
        background.shutdown(wait=True)
    outputs = exported.result()
    st.info = {k: st.info[k] for k in STAGES if k in st.info}  # the stage order

    patch_rows = []
    for p in range(n_patches):
        d = dmaps[p].values
        patch_rows.append(
            {
                "patch": p,
                **spring_info[p],
                **fit_info[p],
                "map_shape": list(dmaps[p].shape),
                "input_distance_max": errors.get(
                    "displaced_from_input_max_per_patch", [None] * n_patches
                )[p],
                "displacement_max": float(np.abs(d).max() / diag),
                "crease_sides": int(lay.creases[lay.patch_curves[p]].sum()),
            }
        )
    notes.extend(_quality_notes(patch_rows, options.layout_seed if route == "sphere" else None))
    summary: dict[str, Any] = {
        "meshfit_fit": PIPELINE_FORMAT,
        "version": __version__,
        "mesh": {
            "name": mesh.name,
            "vertices": int(mesh.n_vertices),
            "faces": int(mesh.n_faces),
            "bbox_diagonal": diag,
            "sha256": mhash,
        },
        "options": json.loads(json.dumps(asdict(options))),  # tuples as JSON lists
        "layout": {
            "source": source if not source.startswith("auto") else "auto",
            # the automatic layout's route and cells (empty where the layout was cached)
            **(layout_report[0] if layout_report else {}),
        },
        "patches_total": n_patches,
        "control_classes": control_classes,
        "stages": st.info,
        "patches": patch_rows,
        "errors": errors,
        "seams": seams,
        "notes": notes,
        "outputs": outputs,
    }

    # ---- report
    if options.report:
        t0 = st.start("report")
        k_rep = _key("report", k_stitch, k_layout, options.image_size)
        cached = st.cached("report", k_rep, ".json")
        images_ok = False
        if cached is not None:
            rec = json.loads(cached.read_text())
            images_ok = all((out / f).is_file() for f in rec["images"])
        from meshfit.report import write_report

        rep = write_report(
            out,
            mesh=mesh,
            layout=lay,
            face_patch=face_patch(),
            grids=grids,
            surfaces=surfaces,
            displaced=displaced_grids,
            spline=spline_grids,
            dmaps=dmaps,
            summary=summary,
            image_size=options.image_size,
            render_images=not images_ok,
            spline_distance=spline_distance[0] if spline_distance else None,
        )
        if not images_ok:
            _write_json(st.path("report", k_rep, ".json"), {"images": rep["images"]})
        st.done("report", t0, cached=images_ok)
        summary["outputs"]["report"] = ["report.html"]
    summary["stages"] = st.info
    summary["seconds_total"] = round(time.perf_counter() - t_all, 4)
    summary["work_done"] = [s for s, i in st.info.items() if not i["cached"] and s != "validate"]
    _write_json(out / "summary.json", summary)
    if options.report:
        # the report's timing table includes the report stage itself
        from meshfit.report import write_html

        write_html(out, summary)
    return summary


#: a patch whose input vertices lie this far (fraction of the bbox diagonal) from the
#: displaced surface gets a note in the summary: the Hausdorff bound the fit is held to
FAR_INPUT = 0.005


def _quality_notes(rows: list[dict], auto_seed: int | None = None) -> list[str]:
    """Warnings about patches whose spring mesh cannot be trusted; with ``auto_seed`` (the
    layout is automatic, from that base rotation), where the layout's patches are flagged,
    how to ask for another rotation."""
    from meshfit.layout.patch import patch_notes

    notes = []
    far = {
        r["patch"]: r["input_distance_max"]
        for r in rows
        if (r.get("input_distance_max") or 0.0) > FAR_INPUT
    }
    if far:
        worst = sorted(far.items(), key=lambda kv: -kv[1])[:5]
        notes.append(
            f"input vertices up to {100 * max(far.values()):.3g}% of the bbox diagonal from the "
            f"displaced surface in {len(far)} patches "
            f"({', '.join(f'patch {p}: {100 * v:.3g}%' for p, v in worst)}): the spring "
            "mesh does not reach part of the patch (a protrusion or pleat inside it): give a "
            "layout file with corners along that feature, or try more patches"
        )
    collapsed = [r["patch"] for r in rows if not np.isfinite(r.get("area_ratio", 1.0))]
    if collapsed:
        notes.append(
            f"spring meshes with collapsed (zero-area) cells in patches {collapsed}: their "
            "fit does not cover the whole patch; split those patches in the layout"
        )
    layout = patch_notes(rows)
    notes.extend(layout)
    if layout and auto_seed is not None:
        from meshfit.layout.auto import SEED_TRIES

        notes.append(
            f"the automatic layout starts from rotation {auto_seed} of its base mesh (the "
            f"next {SEED_TRIES - 1} are tried where its curves cross or a patch is a sliver): "
            "another start (--layout-seed N, FitOptions.layout_seed) gives other patches"
        )
    finer = {r["patch"]: r["finer"] for r in rows if r.get("finer", 0)}
    if finer:
        which = ", ".join(f"patch {p}: {plural(k, 'level')}" for p, k in finer.items())
        notes.append(
            "spring meshes made finer than the patch's vertex count to reach a protrusion or "
            f"pleat inside it ({which}): their displacement maps are larger"
        )
    folded = {r["patch"]: r["folded"] for r in rows if r.get("folded", 0)}
    if folded:
        worst = sorted(folded.items(), key=lambda kv: -kv[1])[:5]
        notes.append(
            f"{plural(sum(folded.values()), 'folded spring-mesh cell')} in "
            f"{plural(len(folded), 'patch')} "
            f"(most: {', '.join(f'patch {p}: {n}' for p, n in worst)})"
        )
    return notes


def spring_patch(patch, *, level=None, max_points=None, rescue=True, follow_folds=False):
    """Spring mesh of one patch: ``(xyz (nu, nv, 3) float64, metrics dict)``: the final
    level's :func:`meshfit.springs.spring_metrics` (without fidelity) and every level's
    folded cells (the same test, by the fold kernel alone)."""
    from meshfit._kernels.springs import folded_cells
    from meshfit.layout.patch import shape_figures
    from meshfit.springs import resample_patch, spring_metrics

    t = time.perf_counter()
    res = resample_patch(
        patch,
        level=level,
        max_points=max_points,
        rescue=rescue,
        follow_folds=follow_folds,
        metrics=False,
    )
    m = patch.mesh
    fin = spring_metrics(m, res.final, fidelity=False)
    folds = [
        int(folded_cells(m.vertices, m.faces, s.points.face, s.points.bary, *s.shape).sum())
        for s in res.levels[:-1]
    ]
    return res.final.xyz.copy(), {
        "shape": list(res.final.shape),
        "levels": len(res.levels),
        "folded": int(fin["folded"]),
        "folded_any_level": int(sum(folds) + fin["folded"]),
        "arc_cv_max": float(fin["arc_cv_max"]),
        "aspect_max": float(fin["aspect_max"]),
        "area_ratio": float(fin["area_ratio"]),
        "sweeps": [int(s) for s in res.sweeps],
        "rescued": bool(res.rescued),
        "evened": bool(res.evened),
        "finer": int(res.finer),
        "seconds": round(time.perf_counter() - t, 4),
        "patch_faces": int(patch.mesh.n_faces),
        **shape_figures(patch),
    }


def patch_payload(patch) -> dict[str, Any]:
    """A patch as plain arrays (picklable, no cached mesh state) for a remote task."""
    return {
        "index": int(patch.index),
        "vertices": np.asarray(patch.mesh.vertices),
        "faces": np.asarray(patch.mesh.faces),
        "corners": np.asarray(patch.corners),
        "sides": [np.asarray(x) for x in patch.sides],
        "face_parent": np.asarray(patch.face_parent),
        "source_face": np.asarray(patch.vertex_source.face),
        "source_bary": np.asarray(patch.vertex_source.bary),
        "features": [
            (np.asarray(f.points.face), np.asarray(f.points.bary)) for f in patch.features
        ],
        "feature_sides": [tuple(int(x) for x in fs) for fs in patch.feature_sides],
    }


def spring_task(item) -> tuple[NDArray[np.float64], dict]:
    """Remote body of one spring-mesh task: ``item = (patch_payload(p), options)``."""
    from meshfit.layout import Patch
    from meshfit.types import SurfaceCurve, SurfacePoints

    d, kw = item
    patch = Patch(
        d["index"],
        Mesh(d["vertices"], d["faces"]),
        d["corners"],
        tuple(d["sides"]),
        d["face_parent"],
        SurfacePoints(d["source_face"], d["source_bary"]),
        tuple(SurfaceCurve(SurfacePoints(f, b), kind="feature") for f, b in d["features"]),
        tuple(d["feature_sides"]),
    )
    return spring_patch(patch, **kw)


#: pipeline side index (0..3, from corner s to s + 1) -> the stitch package's side name
_SIDE_NAME = ("v0", "u1", "v1", "u0")
#: grid index of each patch corner 0..3 (side s runs from corner s to corner s + 1)
_CORNER_SLOT = ((0, 0), (-1, 0), (-1, -1), (0, -1))


def _layout_network(layout, continuity: str, creases=None):
    """The stitch network from the layout's topology: a shared boundary for every curve two
    patches share, a corner class for every layout corner (the grids' positions need not
    be matched, so curves between the same corners never get confused); boundaries on the
    curves marked in ``creases`` are C0."""
    from meshfit.stitch import Network, SharedBoundary

    users: dict[int, list[tuple[int, int]]] = {}
    for p in range(layout.n_patches):
        for s in range(4):
            users.setdefault(int(layout.patch_curves[p, s]), []).append((p, s))

    def forward(p: int, s: int) -> bool:  # the side's parameter runs along its curve
        return (s in (0, 1)) != bool(layout.patch_reversed[p, s])

    boundaries = []
    for curve, uses in sorted(users.items()):
        if len(uses) != 2:
            continue
        (pa, sa), (pb, sb) = sorted(uses)
        c = "C0" if continuity == "C0" or (creases is not None and creases[curve]) else "G1"
        rev = forward(pa, sa) != forward(pb, sb)
        boundaries.append(SharedBoundary(pa, _SIDE_NAME[sa], pb, _SIDE_NAME[sb], rev, c))
    by_corner: dict[int, list[tuple[int, int, int]]] = {}
    for p in range(layout.n_patches):
        for s, c in enumerate(layout.patch_corners(p).tolist()):
            i, j = _CORNER_SLOT[s]
            by_corner.setdefault(int(c), []).append((p, i, j))
    corners = tuple(tuple(v) for _, v in sorted(by_corner.items()))
    return Network(layout.n_patches, tuple(boundaries), corners)


def _stitch_g1(surfaces, notes: list[str], layout, creases=None) -> list:
    """G1 across shared boundaries and at corners with :mod:`meshfit.stitch`; boundaries
    on the layout curves marked in ``creases`` stay C0."""
    try:
        from meshfit.stitch import stitch_surfaces
    except ImportError:
        notes.append("continuity g1 needs meshfit.stitch, which is not installed: C0 only")
        return surfaces
    return stitch_surfaces(surfaces, _layout_network(layout, "G1", creases))


def _stitch_maps(layout, surfaces, dmaps, notes: list[str], match: bool) -> list:
    """Crack-free displacement seams with :mod:`meshfit.stitch` (unchanged without it).

    With ``match`` the maps first take equal texel counts along shared boundaries
    (:func:`meshfit.stitch.match_map_shapes`), so the seams are closed at every output
    resolution.
    """
    try:
        from meshfit.stitch import match_map_shapes, stitch_displacements
    except ImportError:
        notes.append("meshfit.stitch is not installed: displacement seams left open")
        return dmaps
    net = _layout_network(layout, "C0")
    if match:
        dmaps = match_map_shapes(surfaces, dmaps, net)
    return stitch_displacements(surfaces, dmaps, net)


def _face_patch(st: _Stages, k_cut: str) -> NDArray[np.int64] | None:
    """Patch of every input face, from the cut stage's file (None without it)."""
    p = st.path("cut", k_cut, ".npz")
    if p.is_file():
        return _load_npz(p)["face_patch"]
    return None


def _write_exports(out: Path, names, surfaces, dmaps, formats, st: _Stages) -> dict[str, list[str]]:
    from meshfit import export
    from meshfit.displacement import write_exr, write_png

    outputs: dict[str, list[str]] = {}
    total = len(formats)
    for i, fmt in enumerate(formats):
        files: list[str] = []
        if fmt == "usd":
            export.export_usd(out / "patches.usda", surfaces, displacements=dmaps, names=names)
            files = ["patches.usda"] + [
                f"patches.{n}.{d.kind}.exr" for n, d in zip(names, dmaps, strict=True)
            ]
        elif fmt == "3dm":
            export.export_3dm(out / "patches.3dm", surfaces, names=names)
            files = ["patches.3dm"]
        elif fmt == "iges":
            labels = [f"P{k}" for k in range(len(names))]
            export.export_iges(out / "patches.igs", surfaces, names=labels)
            files = ["patches.igs"]
        elif fmt == "step":
            export.export_step(out / "patches.step", surfaces, names=names)
            files = ["patches.step"]
        elif fmt == "obj":
            # the spline on the displaced surface's vertex grid (8 per control point would
            # make the file about 15 times larger on a fit of 16 x 16 controls)
            shapes = [d.shape[:2] for d in dmaps]
            export.export_objs(
                {out / "displaced.obj": dmaps, out / "spline.obj": None},
                surfaces,
                names=names,
                shape=shapes,
            )
            files = ["displaced.obj", "spline.obj"]
        elif fmt == "glb":
            export.export_gltf(out / "displaced.glb", surfaces, displacements=dmaps, names=names)
            files = ["displaced.glb"]
        elif fmt in ("exr", "png"):
            folder = out / "maps"
            folder.mkdir(exist_ok=True)
            for n, d in zip(names, dmaps, strict=True):
                f = f"maps/{n}.{d.kind}.{fmt}"
                (write_exr if fmt == "exr" else write_png)(d, out / f)
                files.append(f)
        outputs[fmt] = files
        st.tick("exports", i + 1, total)
    return outputs


def load_fit(out: str | os.PathLike) -> dict[str, Any]:
    """The summary of a finished run (``out/summary.json``)."""
    path = Path(out) / "summary.json"
    if not path.is_file():
        raise InputError(f"{path}: no fit summary (run meshfit fit first)")
    return json.loads(path.read_text())
