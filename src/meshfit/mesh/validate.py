"""Mesh validation and repair.

:func:`find_problems` lists every problem of a vertex/face array pair; :func:`repair_arrays`
removes what can be removed safely (degenerate, duplicate, back-to-back and non-finite faces,
unreferenced vertices) and makes face orientation consistent, returning index maps.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from meshfit import errors, tol
from meshfit._kernels import topology as _kt
from meshfit._words import plural
from meshfit.mesh import topology

__all__ = [
    "Finding",
    "RepairReport",
    "clean_edge_table",
    "find_problems",
    "raise_first",
    "repair_arrays",
]


#: the end of the message of a validation error that ``repair=True`` fixes (the command line
#: replaces it with its own flag)
REPAIR_HINT = " (load with repair=True to fix it)"


@dataclass(frozen=True)
class Finding:
    """One validation problem.

    Attributes
    ----------
    kind : str
        Machine-readable name, equal to the ``kind`` of the matching error class.
    message : str
        Human-readable sentence naming the first offending element.
    first : tuple of int
        First offending face ``(f,)``, vertex ``(v,)`` or edge ``(v0, v1)``.
    count : int
        Number of offending elements.
    repairable : bool
        Whether ``repair=True`` removes the problem.
    """

    kind: str
    message: str
    first: tuple[int, ...]
    count: int
    repairable: bool

    @property
    def error_class(self) -> type[errors.MeshValidationError]:
        return _ERRORS[self.kind]

    def to_error(self) -> errors.MeshValidationError:
        hint = REPAIR_HINT if self.repairable else ""
        return self.error_class(self.message + hint, first=self.first, count=self.count)

    def to_dict(self) -> dict:
        return {
            "kind": self.kind,
            "message": self.message,
            "first": list(self.first),
            "count": self.count,
            "repairable": self.repairable,
        }


_ERRORS: dict[str, type[errors.MeshValidationError]] = {
    c.kind: c
    for c in (
        errors.EmptyMeshError,
        errors.NonFiniteError,
        errors.IndexRangeError,
        errors.DegenerateFaceError,
        errors.DuplicateFaceError,
        errors.NonManifoldEdgeError,
        errors.NonManifoldVertexError,
        errors.OrientationError,
        errors.UnreferencedVertexError,
    )
}


def _area2_limit(diag: float) -> float:
    """Largest squared cross-product norm of a degenerate face (twice its area, squared), for
    a bounding-box diagonal ``diag``."""
    return (2.0 * tol.DEGENERATE_AREA * diag * diag) ** 2


def _degenerate_faces(vertices: NDArray, faces: NDArray) -> NDArray[np.bool_]:
    """Faces with a repeated index or (near-)zero area, relative to the bbox diagonal."""
    rep = (faces[:, 0] == faces[:, 1]) | (faces[:, 1] == faces[:, 2]) | (faces[:, 2] == faces[:, 0])
    p = vertices[faces]
    with np.errstate(invalid="ignore", over="ignore"):  # inf coordinates give inf / nan areas
        cross = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
        area2 = np.einsum("ij,ij->i", cross, cross)
    mask = np.zeros(vertices.shape[0], dtype=bool)
    mask[faces.reshape(-1)] = True
    used = vertices[mask]
    finite = used[np.isfinite(used).all(axis=1)]
    diag = float(np.linalg.norm(finite.max(axis=0) - finite.min(axis=0))) if finite.size else 0.0
    limit = _area2_limit(diag)
    with np.errstate(invalid="ignore"):
        small = ~(area2 > limit)
    return rep | small


def _row_keys(rows: NDArray[np.int64]) -> NDArray:
    """One sortable scalar per row of a (n, 3) non-negative int array (equal rows, equal keys)."""
    m = int(rows.max()) + 1 if rows.size else 1
    if m < 2**21:
        return (rows[:, 0] * m + rows[:, 1]) * m + rows[:, 2]
    return np.ascontiguousarray(rows).view(np.dtype((np.void, rows.dtype.itemsize * 3))).ravel()


def _duplicate_faces(faces: NDArray) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
    """Faces repeating an earlier face's vertex set.

    Returns ``(duplicate, back_to_back)``: ``duplicate`` marks every copy after the first
    of a vertex set; ``back_to_back`` marks *all* faces of a set that occurs with both
    windings (a zero-volume fin, which no face of it belongs to the surface).
    """
    nf = faces.shape[0]
    srt = np.sort(faces, axis=1)
    _, first, inverse, counts = np.unique(
        _row_keys(srt), return_index=True, return_inverse=True, return_counts=True
    )
    inverse = inverse.reshape(-1)
    dup = np.ones(nf, dtype=bool)
    dup[first] = False
    # winding parity: rotate each face so its smallest index comes first; the winding is
    # then told by whether the other two ascend
    k = np.argmin(faces, axis=1)
    rolled = faces[np.arange(nf)[:, None], (k[:, None] + np.arange(3)) % 3]
    parity = (rolled[:, 1] > rolled[:, 2]).astype(np.int8)  # 0: ascending after the minimum
    multi = counts[inverse] > 1
    back = np.zeros(nf, dtype=bool)
    if multi.any():
        grp = inverse[multi]
        par = parity[multi]
        has0 = np.zeros(counts.size, dtype=bool)
        has1 = np.zeros(counts.size, dtype=bool)
        has0[grp[par == 0]] = True
        has1[grp[par == 1]] = True
        mixed = has0 & has1
        back = mixed[inverse]
    return dup, back


#: the fast test leaves faces within this relative margin of the degenerate-area limit to
#: :func:`find_problems`, so rounding in the two area formulas cannot tell them apart
_AREA_MARGIN = 1e-6


def clean_edge_table(
    vertices: NDArray[np.float64], faces: NDArray[np.int64]
) -> topology.EdgeTable | None:
    """The edge table of a mesh that has no problem at all, ``None`` otherwise.

    A fast test (two linear-time kernels besides the edge table) that is never wrong when it
    says clean: ``clean_edge_table(v, f) is not None`` implies ``find_problems(v, f) == []``.
    It returns ``None`` for every mesh with a problem and for clean meshes with a face within
    a relative ``1e-6`` of the degenerate-area limit; :func:`find_problems` then decides.

    Parameters
    ----------
    vertices : (nv, 3) float64
    faces : (nf, 3) int64

    Returns
    -------
    EdgeTable or None
        :func:`meshfit.mesh.topology.edge_table` of ``faces`` when the mesh is clean.
    """
    nv = vertices.shape[0]
    if nv == 0 or faces.shape[0] == 0:
        return None
    v = np.ascontiguousarray(vertices, dtype=np.float64)
    f = np.ascontiguousarray(faces, dtype=np.int64)
    if not _kt.simple_ok(v, f):
        return None
    diag = float(np.linalg.norm(v.max(axis=0) - v.min(axis=0)))
    floor = _area2_limit(diag) * (1.0 + _AREA_MARGIN)
    table = topology.edge_table(f, nv)
    if not _kt.manifold_ok(v, f, table.edge_count, table.order, table.start, floor):
        return None
    return table


def find_problems(vertices: NDArray[np.float64], faces: NDArray[np.int64]) -> list[Finding]:
    """Every validation problem of a triangle mesh given as arrays.

    Parameters
    ----------
    vertices : (nv, 3) float64
    faces : (nf, 3) int64

    Returns
    -------
    list of Finding
        In a fixed order, most serious first: empty, non-finite, index range, non-manifold
        edges, non-manifold vertices, degenerate, duplicate, unreferenced, orientation.
        Topological checks are skipped while indices are out of range.
    """
    out: list[Finding] = []
    nv, nf = vertices.shape[0], faces.shape[0]
    if nv == 0 or nf == 0:
        what = "no vertices" if nv == 0 else "no faces"
        return [Finding("empty", f"mesh is empty: it has {what}", (), 0, False)]
    bad_v = ~np.isfinite(vertices).all(axis=1)
    if bad_v.any():
        idx = np.flatnonzero(bad_v)
        out.append(
            Finding(
                "non_finite",
                f"{plural(idx.size, 'vertex')} with NaN or infinite coordinates "
                f"(first: vertex {idx[0]} = {vertices[idx[0]].tolist()})",
                (int(idx[0]),),
                int(idx.size),
                True,
            )
        )
    bad_f = ((faces < 0) | (faces >= nv)).any(axis=1)
    if bad_f.any():
        idx = np.flatnonzero(bad_f)
        out.append(
            Finding(
                "index_range",
                f"{plural(idx.size, 'face')} with vertex indices outside [0, {nv}) "
                f"(first: face {idx[0]} = {faces[idx[0]].tolist()})",
                (int(idx[0]),),
                int(idx.size),
                False,
            )
        )
        return out
    # faces with a repeated index have no proper edges (a self-loop, an edge used twice): they
    # are reported as degenerate and left out of the topological checks
    rep = (faces[:, 0] == faces[:, 1]) | (faces[:, 1] == faces[:, 2]) | (faces[:, 2] == faces[:, 0])
    tidx = np.flatnonzero(~rep)  # face id of each row of tf
    tf = faces[tidx]
    table = topology.edge_table(tf, nv)
    nm = np.flatnonzero(table.edge_count > 2)
    if nm.size:
        e = table.edges[nm[0]]
        fs = sorted(tidx[table.halfedges_of(int(nm[0])) // 3].tolist())
        # repairable when dropping duplicate / back-to-back / degenerate faces fixes every one
        dup, back = _duplicate_faces(faces)
        dropped = (dup | back | _degenerate_faces(vertices, faces))[tidx]
        left = np.bincount(
            table.halfedge_edge[np.repeat(~dropped, 3)], minlength=table.edges.shape[0]
        )
        fixable = bool((left[nm] <= 2).all())
        cause = " (all caused by duplicate or back-to-back faces)" if fixable else ""
        out.append(
            Finding(
                "non_manifold_edge",
                f"{plural(nm.size, 'non-manifold edge')} shared by more than two faces "
                f"(first: edge ({e[0]}, {e[1]}) in faces {fs}){cause}",
                (int(e[0]), int(e[1])),
                int(nm.size),
                fixable,
            )
        )
    if tf.size:
        fan, n_fans = topology.corner_fans(tf, nv, table)
        fan_vertex = np.empty(n_fans, dtype=np.int64)  # corners of one fan share their vertex
        fan_vertex[fan] = tf.reshape(-1)
        fans_per_vertex = np.bincount(fan_vertex, minlength=nv)
    else:
        fans_per_vertex = np.zeros(nv, dtype=np.int64)
    nmv = np.flatnonzero(fans_per_vertex > 1)
    if nm.size:  # vertices of non-manifold edges are reported with the edges
        nmv = np.setdiff1d(nmv, table.edges[nm].reshape(-1))
    if nmv.size:
        out.append(
            Finding(
                "non_manifold_vertex",
                f"{plural(nmv.size, 'non-manifold vertex')} where separate fans of faces "
                f"meet (first: vertex {nmv[0]}, {fans_per_vertex[nmv[0]]} fans)",
                (int(nmv[0]),),
                int(nmv.size),
                False,
            )
        )
    deg = _degenerate_faces(vertices, faces) & ~bad_v[faces].any(axis=1)
    if deg.any():
        idx = np.flatnonzero(deg)
        out.append(
            Finding(
                "degenerate_face",
                f"{plural(idx.size, 'degenerate face')} (zero area or repeated vertex; "
                f"first: face {idx[0]} = {faces[idx[0]].tolist()})",
                (int(idx[0]),),
                int(idx.size),
                True,
            )
        )
    dup, back = _duplicate_faces(faces)
    if dup.any():
        idx = np.flatnonzero(dup)
        srt = np.sort(faces, axis=1)
        orig = int(np.flatnonzero((srt == srt[idx[0]]).all(axis=1))[0])
        nback = int(back.sum()) // 2
        extra = f", {nback} of them back-to-back (opposite winding)" if nback else ""
        out.append(
            Finding(
                "duplicate_face",
                f"{plural(idx.size, 'duplicate face')}{extra} (first: face {idx[0]} "
                f"repeats face {orig}, vertices {sorted(faces[orig].tolist())})",
                (int(idx[0]),),
                int(idx.size),
                True,
            )
        )
    referenced = np.zeros(nv, dtype=bool)
    referenced[faces.reshape(-1)] = True
    if not referenced.all():
        idx = np.flatnonzero(~referenced)
        out.append(
            Finding(
                "unreferenced_vertex",
                f"{plural(idx.size, 'vertex')} not used by any face (first: vertex {idx[0]})",
                (int(idx[0]),),
                int(idx.size),
                True,
            )
        )
    tail, _head = topology.halfedges(tf)
    two = np.flatnonzero(table.edge_count == 2)
    ha = table.order[table.start[two]]
    hb = table.order[table.start[two] + 1]
    same_dir = tail[ha] == tail[hb]
    if same_dir.any():
        i = np.flatnonzero(same_dir)
        e = table.edges[two[i[0]]]
        # repairable unless the faces a repair keeps form a non-orientable surface
        keep = ~(bad_v[faces].any(axis=1) | deg | dup | back)
        try:
            _orient(faces[keep], nv)
            orientable, why = True, ""
        except errors.OrientationError:
            orientable, why = False, "; the surface is not orientable (a Moebius-like twist)"
        out.append(
            Finding(
                "inconsistent_orientation",
                f"{plural(i.size, 'edge')} where neighbouring faces have opposite "
                f"winding (first: edge ({e[0]}, {e[1]}) between faces "
                f"{int(tidx[ha[i[0]] // 3])} and {int(tidx[hb[i[0]] // 3])}){why}",
                (int(e[0]), int(e[1])),
                int(i.size),
                orientable,
            )
        )
    if all(x.repairable for x in out if x.kind != "non_manifold_vertex"):
        drop = bad_v[faces].any(axis=1) | deg | dup | back
        if drop.any() or nmv.size:
            out = _simulate_repair(vertices, faces, drop, nmv, out)
    return out


_DROPPING = ("non_finite", "non_manifold_edge", "degenerate_face", "duplicate_face")


def _simulate_repair(
    vertices: NDArray,
    faces: NDArray,
    drop: NDArray[np.bool_],
    nmv_before: NDArray[np.int64],
    findings: list[Finding],
) -> list[Finding]:
    """Set the ``repairable`` flags from the faces :func:`repair_arrays` would keep.

    A non-manifold vertex is repairable when dropping faces removes it. The face-dropping
    findings are not when the drop would leave no face, a new non-manifold vertex (two
    holes meeting at a vertex where back-to-back faces leave a surface) or a non-orientable
    surface.
    """
    nv = vertices.shape[0]
    kept = faces[~drop]
    why = ""
    nmv_left = nmv_before
    if kept.size == 0:
        why = "no face"
    else:
        table = topology.edge_table(kept, nv)
        fan, n_fans = topology.corner_fans(kept, nv, table)
        fan_vertex = np.empty(n_fans, dtype=np.int64)
        fan_vertex[fan] = kept.reshape(-1)
        after = np.flatnonzero(np.bincount(fan_vertex, minlength=nv) > 1)
        nmv_left = np.intersect1d(after, nmv_before)
        new = np.setdiff1d(after, nmv_before)
        if new.size:
            why = f"a non-manifold vertex (first: vertex {new[0]})"
        else:
            tail, _ = topology.halfedges(kept)
            two = table.start[table.edge_count == 2]
            if (tail[table.order[two]] == tail[table.order[two + 1]]).any():
                try:
                    _orient(kept, nv)
                except errors.OrientationError:
                    why = "a non-orientable surface"
    note = f"; repair cannot fix it: dropping the faces would leave {why}" if why else ""
    out = []
    for x in findings:
        if x.kind == "non_manifold_vertex" and nmv_left.size == 0 and not why:
            x = Finding(
                x.kind,
                x.message + " (removed by dropping the faces repair drops)",
                x.first,
                x.count,
                True,
            )
        elif x.kind in _DROPPING and why:
            x = Finding(x.kind, x.message + note, x.first, x.count, False)
        out.append(x)
    return out


def raise_first(findings: list[Finding], *, where: str = "") -> None:
    """Raise the error of the first finding, prefixed with ``where`` (e.g. a file name)."""
    if findings:
        err = findings[0].to_error()
        if len(findings) > 1:
            more = "; also: " + "; ".join(f.kind.replace("_", " ") for f in findings[1:])
        else:
            more = ""
        msg = f"{where}: {err}{more}" if where else f"{err}{more}"
        raise type(err)(msg, first=err.first, count=err.count)


@dataclass
class RepairReport:
    """What :func:`repair_arrays` changed.

    Attributes
    ----------
    vertex_map : (nv_in,) int64
        New index of every input vertex, -1 where it was dropped.
    face_map : (nf_in,) int64
        New index of every input face, -1 where it was dropped.
    flipped_faces : (k,) int64
        Input face indices whose winding was reversed for consistent orientation.
    fixed : list of Finding
        The problems found before the repair.
    """

    vertex_map: NDArray[np.int64]
    face_map: NDArray[np.int64]
    flipped_faces: NDArray[np.int64]
    fixed: list[Finding] = field(default_factory=list)

    def summary(self) -> str:
        parts = [f"{f.kind.replace('_', ' ')}: {f.count}" for f in self.fixed]
        dropped_f = int((self.face_map < 0).sum())
        dropped_v = int((self.vertex_map < 0).sum())
        return (
            f"repaired ({', '.join(parts) or 'nothing to do'}): dropped "
            f"{plural(dropped_f, 'face')} and {plural(dropped_v, 'vertex')}, flipped "
            f"{plural(self.flipped_faces.size, 'face')}"
        )


def _orient(faces: NDArray[np.int64], nv: int) -> NDArray[np.int64]:
    """Faces to flip so that every manifold edge is used in opposite directions.

    Breadth-first over each component from its lowest face; the winding of the majority of
    a component's faces is kept (the minority is flipped). Raises OrientationError when a
    component is not orientable.
    """
    table = topology.edge_table(faces, nv)
    tail, _ = topology.halfedges(faces)
    two = np.flatnonzero(table.edge_count == 2)
    ha = table.order[table.start[two]]
    hb = table.order[table.start[two] + 1]
    fa, fb = ha // 3, hb // 3
    same = (tail[ha] == tail[hb]).astype(np.int8)  # 1: faces must differ in flip state
    nf = faces.shape[0]
    adj: list[list[tuple[int, int]]] = [[] for _ in range(nf)]
    for a, b, s in zip(fa.tolist(), fb.tolist(), same.tolist(), strict=True):
        adj[a].append((b, s))
        adj[b].append((a, s))
    flip = np.full(nf, -1, dtype=np.int8)
    comp = np.full(nf, -1, dtype=np.int64)
    for seed in range(nf):
        if flip[seed] >= 0:
            continue
        flip[seed] = 0
        comp[seed] = seed
        stack = [seed]
        while stack:
            f = stack.pop()
            for g, s in adj[f]:
                want = flip[f] ^ s
                if flip[g] < 0:
                    flip[g] = want
                    comp[g] = seed
                    stack.append(g)
                elif flip[g] != want:
                    raise errors.OrientationError(
                        f"the surface is not orientable: faces {f} and {g} cannot both be "
                        "made consistent",
                        first=(int(f),),
                        count=1,
                    )
    size = np.bincount(comp, minlength=nf)
    flipped = np.bincount(comp, weights=flip, minlength=nf)
    invert = 2 * flipped > size  # flip the minority of each component, not the majority
    flip[invert[comp]] ^= 1
    return np.flatnonzero(flip == 1)


def repair_arrays(
    vertices: NDArray[np.float64],
    faces: NDArray[np.int64],
    vertex_colors: NDArray[np.uint8] | None = None,
):
    """Remove the repairable problems of a mesh.

    Drops faces that touch non-finite vertices, degenerate faces, later copies of duplicate
    faces and both faces of back-to-back pairs, then unreferenced vertices; flips faces to a
    consistent orientation. Problems that cannot be repaired (indices out of range,
    non-manifold edges or vertices that remain, an empty result) raise.

    Parameters
    ----------
    vertices : (nv, 3) float64
    faces : (nf, 3) int64
    vertex_colors : (nv, 3 | 4) uint8, optional

    Returns
    -------
    vertices : (nv', 3) float64
    faces : (nf', 3) int64
    vertex_colors : (nv', 3 | 4) uint8 or None
    report : RepairReport
    """
    findings = find_problems(vertices, faces)
    fatal = [f for f in findings if not f.repairable]
    if fatal and fatal[0].kind in ("empty", "index_range"):
        raise_first(fatal)
    nv, nf = vertices.shape[0], faces.shape[0]
    bad_v = ~np.isfinite(vertices).all(axis=1)
    drop = bad_v[faces].any(axis=1)
    drop |= _degenerate_faces(vertices, faces)
    dup, back = _duplicate_faces(faces)
    drop |= dup | back
    keep = np.flatnonzero(~drop)
    face_map = np.full(nf, -1, dtype=np.int64)
    face_map[keep] = np.arange(keep.size)
    kept = faces[keep]
    used = np.zeros(nv, dtype=bool)
    used[kept.reshape(-1)] = True
    vertex_map = np.full(nv, -1, dtype=np.int64)
    vertex_map[used] = np.arange(int(used.sum()))
    new_faces = vertex_map[kept]
    new_vertices = vertices[used]
    new_colors = vertex_colors[used] if vertex_colors is not None else None
    after = find_problems(new_vertices, new_faces)
    remaining = [f for f in after if f.kind != "inconsistent_orientation"]
    if remaining:
        raise_first(remaining, where="after repair")
    flipped_new = (
        _orient(new_faces, new_vertices.shape[0]) if after else np.zeros(0, dtype=np.int64)
    )
    if flipped_new.size:
        new_faces = new_faces.copy()
        new_faces[flipped_new] = new_faces[flipped_new][:, ::-1]
    flipped = keep[flipped_new]
    report = RepairReport(vertex_map, face_map, flipped.astype(np.int64), findings)
    return new_vertices, new_faces, new_colors, report
