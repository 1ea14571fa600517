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
    "area2_limit",
    "clean_edge_table",
    "degenerate_faces",
    "find_problems",
    "inside_out_finding",
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
        errors.CoordinateRangeError,
        errors.IndexRangeError,
        errors.DegenerateFaceError,
        errors.DuplicateFaceError,
        errors.NonManifoldEdgeError,
        errors.NonManifoldVertexError,
        errors.OrientationError,
        errors.UnreferencedVertexError,
    )
}


def area2_limit(diag: float) -> float:
    """Largest squared cross-product norm of a degenerate face (twice its area, squared):
    ``(2 tol.DEGENERATE_AREA diag^2)^2``, an area scaled to the mesh rather than a constant.

    Parameters
    ----------
    diag : float
        Bounding-box diagonal of the used vertices, model units.

    Returns
    -------
    float
        Model units to the fourth power.
    """
    return (2.0 * tol.DEGENERATE_AREA * diag * diag) ** 2


def degenerate_faces(vertices: NDArray, faces: NDArray, limit: float) -> NDArray[np.bool_]:
    """The validator's degenerate faces: a repeated index, or a squared cross product (twice
    the area, squared) of at most ``limit`` (`area2_limit`), or not a number.

    Parameters
    ----------
    vertices : (nv, 3) float64
    faces : (nf, 3) int64
        Indices in range.
    limit : float
        Model units to the fourth power.

    Returns
    -------
    (nf,) bool
    """
    rep = (faces[:, 0] == faces[:, 1]) | (faces[:, 1] == faces[:, 2]) | (faces[:, 2] == faces[:, 0])
    p = vertices[faces]
    with np.errstate(invalid="ignore", over="ignore"):  # inf coordinates give inf / nan areas
        cross = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
        area2 = np.einsum("ij,ij->i", cross, cross)
        small = ~(area2 > limit)
    return rep | small


def _degenerate_faces(vertices: NDArray, faces: NDArray) -> NDArray[np.bool_]:
    """Faces with a repeated index or (near-)zero area, relative to the bbox diagonal of the
    used, finite vertices."""
    mask = np.zeros(vertices.shape[0], dtype=bool)
    mask[faces.reshape(-1)] = True
    used = vertices[mask]
    finite = used[np.isfinite(used).all(axis=1)]
    diag = float(np.linalg.norm(finite.max(axis=0) - finite.min(axis=0))) if finite.size else 0.0
    return degenerate_faces(vertices, faces, area2_limit(diag))


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
#: an empty repair's message blames 32-bit coordinates whose step at their magnitude is
#: over this share of the mesh's extent
QUANTIZED_SHARE = 1e-3


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
    if not _kt.simple_ok(v, f) or np.abs(v).max() > tol.MAX_COORDINATE:
        return None
    diag = float(np.linalg.norm(v.max(axis=0) - v.min(axis=0)))
    floor = area2_limit(diag) * (1.0 + _AREA_MARGIN)
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
        In a fixed order, most serious first: empty, non-finite, coordinate range, index
        range, non-manifold edges, non-manifold vertices, degenerate, duplicate,
        unreferenced, orientation.
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
    with np.errstate(invalid="ignore"):
        huge = ~bad_v & (np.abs(vertices).max(axis=1) > tol.MAX_COORDINATE)
    if huge.any():
        idx = np.flatnonzero(huge)
        out.append(
            Finding(
                "coordinate_range",
                f"{plural(idx.size, 'vertex')} with coordinates beyond +-{tol.MAX_COORDINATE:g}"
                f" (first: vertex {idx[0]} = {vertices[idx[0]].tolist()}): distances between "
                "them overflow; scale the mesh down",
                (int(idx[0]),),
                int(idx.size),
                False,
            )
        )
        return out
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
        # the repair drops duplicate / back-to-back / degenerate faces and splits the rest
        dup, back = _duplicate_faces(faces)
        dropped = (dup | back | _degenerate_faces(vertices, faces))[tidx]
        left = np.bincount(
            table.halfedge_edge[np.repeat(~dropped, 3)], minlength=table.edges.shape[0]
        )
        by_drops = bool((left[nm] <= 2).all())
        cause = (
            " (all caused by duplicate or back-to-back faces)"
            if by_drops
            else " (repair splits the sheets apart along them)"
        )
        out.append(
            Finding(
                "non_manifold_edge",
                f"{plural(nm.size, 'non-manifold edge')} shared by more than two faces "
                f"(first: edge ({e[0]}, {e[1]}) in faces {fs}){cause}",
                (int(e[0]), int(e[1])),
                int(nm.size),
                True,
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
                f"meet (first: vertex {nmv[0]}, {fans_per_vertex[nmv[0]]} fans; repair gives "
                "each fan its own copy)",
                (int(nmv[0]),),
                int(nmv.size),
                True,
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
    if out and all(x.repairable for x in out):
        out = _check_repair(vertices, faces, out)
    return out


def _check_repair(vertices: NDArray, faces: NDArray, findings: list[Finding]) -> list[Finding]:
    """The findings, marked not repairable (with the reason) when the repair itself fails:
    nothing left, or a surface that cannot be oriented."""
    try:
        _repair_core(vertices, faces)
    except errors.MeshValidationError as exc:
        why = str(exc).split(" (")[0]
        note = f"; repair cannot fix it: {why}"
        out = []
        for x in findings:
            if x.kind in ("inconsistent_orientation", *_DROPPING, "non_manifold_vertex"):
                x = Finding(x.kind, x.message + note, x.first, x.count, False)
            out.append(x)
        return out
    return findings


_DROPPING = ("non_finite", "non_manifold_edge", "degenerate_face", "duplicate_face")


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
        Input face indices whose winding was reversed: for consistent orientation, or
        because their closed component was inside out (negative signed volume).
    fixed : list of Finding
        The problems found before the repair.
    vertex_parent : (nv',) int64
        Input vertex of every output vertex. Where non-manifold edges or vertices were
        split, the copies come after the kept vertices (``vertex_map`` names the first).
    inverted_components : int
        Closed components turned right side out.
    """

    vertex_map: NDArray[np.int64]
    face_map: NDArray[np.int64]
    flipped_faces: NDArray[np.int64]
    fixed: list[Finding] = field(default_factory=list)
    vertex_parent: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, np.int64))
    inverted_components: int = 0

    @property
    def split_vertices(self) -> int:
        """Copies made where non-manifold edges and vertices were split apart."""
        return int(self.vertex_parent.size - (self.vertex_map >= 0).sum())

    def changed(self) -> bool:
        """Whether the repair changed anything."""
        return bool(
            self.fixed
            or self.inverted_components
            or (self.face_map < 0).any()
            or (self.vertex_map < 0).any()
        )

    def summary(self) -> str:
        parts = [f"{f.kind.replace('_', ' ')}: {f.count}" for f in self.fixed]
        if self.inverted_components:
            parts.append(f"inside out: {plural(self.inverted_components, 'component')}")
        dropped_f = int((self.face_map < 0).sum())
        dropped_v = int((self.vertex_map < 0).sum())
        split = (
            f", split {plural(self.split_vertices, 'vertex')} apart" if self.split_vertices else ""
        )
        return (
            f"repaired ({', '.join(parts) or 'nothing to do'}): dropped "
            f"{plural(dropped_f, 'face')} and {plural(dropped_v, 'vertex')}{split}, flipped "
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


def _split_fans(faces: NDArray[np.int64], nv: int) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Faces with one vertex per fan of corners (non-manifold edges and vertices split
    apart), and the vertex each output vertex copies (copies after the first ``nv``)."""
    table = topology.edge_table(faces, nv)
    fan, n_fans = topology.corner_fans(faces, nv, table)
    if n_fans == nv:
        return faces, np.arange(nv, dtype=np.int64)
    corner_v = faces.reshape(-1)
    fan_vertex = np.empty(n_fans, dtype=np.int64)
    fan_vertex[fan] = corner_v
    # the fan of each vertex's first corner keeps the vertex; the others are new copies
    first_corner = np.full(nv, -1, dtype=np.int64)
    order = np.arange(corner_v.size)[::-1]
    first_corner[corner_v[order]] = order
    keeps = np.zeros(n_fans, dtype=bool)
    keeps[fan[first_corner]] = True
    new_id = np.empty(n_fans, dtype=np.int64)
    new_id[keeps] = fan_vertex[keeps]
    extra = np.flatnonzero(~keeps)
    new_id[extra] = nv + np.arange(extra.size)
    parent = np.concatenate([np.arange(nv), fan_vertex[extra]]).astype(np.int64)
    return new_id[fan].reshape(-1, 3), parent


def inside_out_finding(vertices: NDArray[np.float64], faces: NDArray[np.int64]) -> Finding | None:
    """The closed components of a valid mesh that are inside out (negative signed volume:
    their normals point inwards), as a repairable Finding, or None.

    Not one of :func:`find_problems`' findings (such a mesh is valid and every kernel works
    on it); the strict command line path reports it, since a fit of it faces the wrong way.

    Parameters
    ----------
    vertices : (nv, 3) float64
    faces : (nf, 3) int64
        A valid mesh's arrays.

    Returns
    -------
    Finding or None
        Kind ``"inside_out"``, ``first`` the first face of such a component, ``count`` the
        number of such components; repairable.
    """
    if faces.shape[0] == 0:
        return None
    inside = _inside_out(vertices, faces)
    if not inside.any():
        return None
    table = topology.edge_table(faces, vertices.shape[0])
    _, comp = topology.face_components(faces.shape[0], topology.face_neighbors(faces, table))
    n = int(np.unique(comp[inside]).size)
    first = int(np.flatnonzero(inside)[0])
    return Finding(
        "inside_out",
        f"{plural(n, 'closed component')} inside out: the normals point inwards (negative "
        f"signed volume; first: face {first})",
        (first,),
        n,
        True,
    )


def _inside_out(vertices: NDArray[np.float64], faces: NDArray[np.int64]) -> NDArray[np.bool_]:
    """Faces of closed components whose signed volume is negative."""
    nv = vertices.shape[0]
    table = topology.edge_table(faces, nv)
    n, comp = topology.face_components(faces.shape[0], topology.face_neighbors(faces, table))
    open_edge = table.edge_count == 1
    is_open = np.zeros(n, dtype=bool)
    he_face = np.arange(faces.size) // 3
    is_open[comp[he_face[open_edge[table.halfedge_edge]]]] = True
    a, b, c = (vertices[faces[:, k]] for k in range(3))
    centre = vertices[faces.reshape(-1)].mean(axis=0)  # volumes about a nearby point
    vol = np.einsum("ij,ij->i", a - centre, np.cross(b - centre, c - centre))
    total = np.bincount(comp, weights=vol, minlength=n)
    return (total < 0)[comp] & ~is_open[comp]


def _nothing_left(
    vertices: NDArray[np.float64],
    faces: NDArray[np.int64],
    bad_v: NDArray[np.bool_],
    flat: NDArray[np.bool_],
    repeated: NDArray[np.bool_],
) -> str:
    """Why the repair kept no face: how many were non-finite, repeated or degenerate, and,
    where degenerate faces dominate and the coordinates are 32-bit floats whose step at
    their magnitude is a sizeable share of the mesh's extent (an STL or a float PLY saved
    far from the origin, as georeferenced scans are), that the file's precision is the
    cause."""
    nonfinite = bad_v[faces].any(axis=1)
    text = (
        f"no face is left after dropping the degenerate, duplicate and back-to-back faces "
        f"(of {faces.shape[0]}: {int((flat & ~nonfinite).sum())} degenerate, "
        f"{int(repeated.sum())} duplicate or back-to-back, {int(nonfinite.sum())} with a "
        "non-finite vertex)"
    )
    good = vertices[np.isfinite(vertices).all(axis=1)]
    if good.size == 0 or not np.array_equal(good.astype(np.float32).astype(np.float64), good):
        return text
    magnitude = float(np.abs(good).max())
    step = float(np.spacing(np.float32(magnitude)))
    extent = float(np.linalg.norm(good.max(axis=0) - good.min(axis=0)))
    if magnitude > 0.0 and step > QUANTIZED_SHARE * extent:
        share = "more than" if step >= extent else f"{step / extent:.1%} of"
        text += (
            f": the coordinates are 32-bit floats of magnitude {magnitude:.3g}, which step by "
            f"{step:.3g} there, {share} the mesh's extent ({extent:.3g}); save it with 64-bit "
            "(double) coordinates, or move it near the origin before saving"
        )
    return text


def _repair_core(vertices: NDArray[np.float64], faces: NDArray[np.int64]):
    """The repair without the findings: (vertices, faces, kept input faces, vertex map,
    vertex parents, flipped output faces, inverted components)."""
    nv = vertices.shape[0]
    bad_v = ~np.isfinite(vertices).all(axis=1)
    drop = bad_v[faces].any(axis=1)
    flat = _degenerate_faces(vertices, faces)
    drop |= flat
    dup, back = _duplicate_faces(faces)
    drop |= dup | back
    keep = np.flatnonzero(~drop)
    if keep.size == 0:
        why = _nothing_left(vertices, faces, bad_v, flat, dup | back)
        raise errors.EmptyMeshError(why, first=(), count=0)
    kept = faces[keep]
    used = np.zeros(nv, dtype=bool)
    used[kept.reshape(-1)] = True
    vertex_map = np.full(nv, -1, dtype=np.int64)
    vertex_map[used] = np.arange(int(used.sum()))
    new_faces, parent_local = _split_fans(vertex_map[kept], int(used.sum()))
    vertex_parent = np.flatnonzero(used)[parent_local]
    new_vertices = vertices[vertex_parent]
    flipped = _orient(new_faces, new_vertices.shape[0])
    flip = np.zeros(new_faces.shape[0], dtype=bool)
    flip[flipped] = True
    oriented = np.where(flip[:, None], new_faces[:, ::-1], new_faces)
    inside = _inside_out(new_vertices, oriented)
    inverted = 0
    if inside.any():
        table = topology.edge_table(oriented, new_vertices.shape[0])
        _, comp = topology.face_components(
            oriented.shape[0], topology.face_neighbors(oriented, table)
        )
        inverted = int(np.unique(comp[inside]).size)
        flip ^= inside
    new_faces = np.where(flip[:, None], new_faces[:, ::-1], new_faces)
    return new_vertices, new_faces, keep, vertex_map, vertex_parent, np.flatnonzero(flip), inverted


def repair_arrays(
    vertices: NDArray[np.float64],
    faces: NDArray[np.int64],
    vertex_colors: NDArray[np.uint8] | None = None,
):
    """Remove the repairable problems of a mesh.

    Drops faces that touch non-finite vertices, degenerate faces, later copies of duplicate
    faces and both faces of back-to-back pairs, then unreferenced vertices; splits the
    sheets meeting at a non-manifold edge or vertex apart (one vertex copy per fan of
    faces); flips faces to a consistent orientation, and turns closed components that are
    inside out (negative signed volume) right side out. Problems that cannot be repaired
    (indices out of range, a non-orientable surface, an empty result) raise.

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
    if fatal and fatal[0].kind in ("empty", "coordinate_range", "index_range"):
        raise_first(fatal)
    nf = faces.shape[0]
    if not findings and not _inside_out(vertices, faces).any():
        # a valid mesh the right way out: nothing to change
        ident = np.arange(vertices.shape[0], dtype=np.int64)
        report = RepairReport(
            ident, np.arange(nf, dtype=np.int64), np.zeros(0, dtype=np.int64), [], ident, 0
        )
        return vertices, faces, vertex_colors, report
    try:
        new_vertices, new_faces, keep, vertex_map, parent, flipped_new, inverted = _repair_core(
            vertices, faces
        )
    except errors.EmptyMeshError as exc:
        raise type(exc)(f"after repair: {exc}", first=exc.first, count=exc.count) from None
    face_map = np.full(nf, -1, dtype=np.int64)
    face_map[keep] = np.arange(keep.size)
    new_colors = vertex_colors[parent] if vertex_colors is not None else None
    after = find_problems(new_vertices, new_faces)
    if after:
        raise_first(after, where="after repair")
    flipped = keep[flipped_new]
    report = RepairReport(
        vertex_map, face_map, flipped.astype(np.int64), findings, parent, inverted
    )
    return new_vertices, new_faces, new_colors, report
