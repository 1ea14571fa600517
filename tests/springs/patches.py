"""Synthetic four-sided patches with known spring meshes: plane, quarter cylinder, sphere cap."""

from __future__ import annotations

import numpy as np

from meshfit.layout.patch import Patch
from meshfit.mesh import Mesh
from meshfit.types import SurfaceCurve, SurfacePoints


def _grid_faces(n: int, m: int, rng) -> np.ndarray:
    idx = np.arange((n + 1) * (m + 1)).reshape(n + 1, m + 1)
    a, b, c, d = (
        idx[:-1, :-1].ravel(),
        idx[1:, :-1].ravel(),
        idx[1:, 1:].ravel(),
        idx[:-1, 1:].ravel(),
    )
    flip = rng.random(a.size) < 0.5
    f1 = np.where(flip[:, None], np.stack([a, b, c], 1), np.stack([a, b, d], 1))
    f2 = np.where(flip[:, None], np.stack([a, c, d], 1), np.stack([b, c, d], 1))
    return np.concatenate([f1, f2])


def param_patch(fn, n: int = 24, m: int = 24, *, jitter: float = 0.25, seed: int = 0) -> Patch:
    """Patch of the map ``fn(s, t) -> (k, 3)`` over ``[0, 1]^2``, triangulated irregularly.

    Corner 0 is (0, 0), corner 1 (1, 0), corner 2 (1, 1), corner 3 (0, 1); the map must be
    oriented so that (dS/ds) x (dS/dt) is the outward normal.
    """
    rng = np.random.default_rng(seed)
    s, t = np.meshgrid(np.linspace(0, 1, n + 1), np.linspace(0, 1, m + 1), indexing="ij")
    inner = (s > 0) & (s < 1) & (t > 0) & (t < 1)
    s = s + np.where(inner, rng.uniform(-jitter / n, jitter / n, s.shape), 0)
    t = t + np.where(inner, rng.uniform(-jitter / m, jitter / m, t.shape), 0)
    verts = fn(s.ravel(), t.ravel())
    mesh = Mesh(verts, _grid_faces(n, m, rng), name="param_patch")
    idx = np.arange((n + 1) * (m + 1)).reshape(n + 1, m + 1)
    corners = np.array([idx[0, 0], idx[-1, 0], idx[-1, -1], idx[0, -1]])
    sides = (idx[:, 0], idx[-1, :], idx[::-1, -1], idx[0, ::-1])
    vs = SurfacePoints(*_vertex_points(mesh))
    return Patch(0, mesh, corners, sides, np.arange(mesh.n_faces), vs)


def _vertex_points(mesh: Mesh):
    indptr, vf = mesh.vertex_faces
    face = vf[indptr[:-1]]
    bary = (mesh.faces[face] == np.arange(mesh.n_vertices)[:, None]).astype(float)
    return face, bary


def plane_map(width: float = 2.0, height: float = 1.0):
    def fn(s, t):
        return np.stack([width * s, height * t, np.zeros_like(s)], axis=1)

    return fn


def cylinder_map(radius: float = 1.0, height: float = 1.5, angle: float = np.pi / 2):
    """Quarter cylinder about z; s runs around (outward normal), t along the axis."""

    def fn(s, t):
        a = angle * s
        return np.stack([radius * np.cos(a), radius * np.sin(a), height * t], axis=1)

    return fn


def cap_map(radius: float = 1.0, half: float = 0.6):
    """A quad on a sphere: the gnomonic square [-half, half]^2 projected onto the sphere."""

    def fn(s, t):
        x = (2 * s - 1) * half
        y = (2 * t - 1) * half
        p = np.stack([x, y, np.ones_like(x)], axis=1)
        return radius * p / np.linalg.norm(p, axis=1, keepdims=True)

    return fn


def with_features(patch: Patch, fn, us=(), vs=(), n: int = 400) -> Patch:
    """The patch with feature curves ``s = c`` (for c in us) and ``t = c`` (for c in vs),
    painted as dense face-point polylines found by closest points."""
    from meshfit.surface import closest_surface_points

    feats, fsides = [], []
    r = np.linspace(0.0, 1.0, n)
    for c in us:
        pts = closest_surface_points(patch.mesh, fn(np.full(n, c), r))
        feats.append(SurfaceCurve(pts, closed=False, kind="feature"))
        fsides.append((0, 2))
    for c in vs:
        pts = closest_surface_points(patch.mesh, fn(r[::-1], np.full(n, c)))
        feats.append(SurfaceCurve(pts, closed=False, kind="feature"))
        fsides.append((1, 3))
    return Patch(
        patch.index,
        patch.mesh,
        patch.corners,
        patch.sides,
        patch.face_parent,
        patch.vertex_source,
        tuple(feats),
        tuple(fsides),
    )


def disk_patch(mesh: Mesh, seed: int, radius: float, index: int = 0) -> Patch:
    """Patch of the faces within graph distance ``radius`` of vertex ``seed`` (a disk), its
    four corners at quarter arc lengths of the boundary loop."""
    from scipy.sparse.csgraph import connected_components, dijkstra

    d = dijkstra(mesh.edge_graph, directed=False, indices=seed, limit=radius * 1.5)
    faces = np.flatnonzero((d[mesh.faces] <= radius).all(axis=1))
    # keep the seed's component and fill holes: the complement's components other than
    # the largest go back into the patch
    inside = np.zeros(mesh.n_faces, dtype=bool)
    inside[faces] = True
    fn = mesh.face_neighbors
    rows = np.repeat(np.arange(mesh.n_faces), 3)
    cols = fn.ravel()
    ok = cols >= 0
    rows, cols = rows[ok], cols[ok]
    from scipy import sparse

    same = inside[rows] == inside[cols]
    g = sparse.csr_matrix(
        (np.ones(same.sum()), (rows[same], cols[same])), shape=(mesh.n_faces,) * 2
    )
    _, lab = connected_components(g, directed=False)
    seed_face = mesh.vertex_faces[1][mesh.vertex_faces[0][seed]]
    out_labels, counts = np.unique(lab[~inside], return_counts=True)
    big_out = out_labels[np.argmax(counts)]
    keep = (lab == lab[seed_face]) | (~inside & (lab != big_out))
    faces = np.flatnonzero(keep)
    used, inv = np.unique(mesh.faces[faces], return_inverse=True)
    sub = Mesh(mesh.vertices[used], inv.reshape(-1, 3), name=f"{mesh.name}-disk")
    assert len(sub.boundary_loops) == 1 and sub.euler_characteristic == 1, "not a disk"
    loop = np.asarray(sub.boundary_loops[0])
    a, b = int(loop[0]), int(loop[1])
    f = sub.faces[np.flatnonzero((sub.faces == a).any(1) & (sub.faces == b).any(1))[0]]
    k = int(np.flatnonzero(f == a)[0])
    if f[(k + 1) % 3] != b:
        loop = loop[::-1]
    arc = np.concatenate(
        [
            [0],
            np.cumsum(
                np.linalg.norm(np.diff(sub.vertices[np.append(loop, loop[0])], axis=0), axis=1)
            ),
        ]
    )
    ks = [int(np.argmin(np.abs(arc[:-1] - q * arc[-1]))) for q in (0, 0.25, 0.5, 0.75)]
    ext = np.append(loop, loop)
    sides = tuple(ext[ks[s] : (ks[s + 1] if s < 3 else ks[0] + len(loop)) + 1] for s in range(4))
    corners = loop[ks]
    vs = SurfacePoints(*_vertex_points(sub))
    return Patch(index, sub, corners, sides, faces, vs)


def _submesh_patch(mesh: Mesh, faces: np.ndarray, corner_xyz: np.ndarray, index: int) -> Patch:
    used, inv = np.unique(mesh.faces[faces], return_inverse=True)
    sub = Mesh(mesh.vertices[used], inv.reshape(-1, 3), name=f"{mesh.name}-patch")
    assert len(sub.boundary_loops) == 1 and sub.euler_characteristic == 1, "not a disk"
    loop = np.asarray(sub.boundary_loops[0])
    a, b = int(loop[0]), int(loop[1])
    f = sub.faces[np.flatnonzero((sub.faces == a).any(1) & (sub.faces == b).any(1))[0]]
    k = int(np.flatnonzero(f == a)[0])
    if f[(k + 1) % 3] != b:
        loop = loop[::-1]
    ks = [int(np.argmin(np.linalg.norm(sub.vertices[loop] - c, axis=1))) for c in corner_xyz]
    start = ks[0]
    loop = np.roll(loop, -start)
    ks = sorted((k - start) % len(loop) for k in ks)
    ext = np.append(loop, loop[0])
    sides = tuple(ext[ks[s] : (ks[s + 1] if s < 3 else len(loop)) + 1] for s in range(4))
    corners = loop[ks]
    vs = SurfacePoints(*_vertex_points(sub))
    return Patch(index, sub, corners, sides, faces, vs)


def cut_patch(mesh: Mesh, center: int, radius: float, *, n: int = 240, index: int = 0) -> Patch:
    """Patch cut out of ``mesh`` along a closed curve: a square of half-size ``radius`` in the
    tangent plane at vertex ``center`` projected onto the surface; corners at its corners."""
    from scipy import sparse
    from scipy.sparse.csgraph import connected_components

    from meshfit.curves import densify_curve
    from meshfit.surface import closest_surface_points, cut_mesh

    indptr, vf = mesh.vertex_faces
    nrm = mesh.face_normals[vf[indptr[center] : indptr[center + 1]]].sum(0)
    nrm /= np.linalg.norm(nrm)
    e1 = np.cross(nrm, [1.0, 0, 0] if abs(nrm[0]) < 0.9 else [0, 1.0, 0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(nrm, e1)
    t = np.linspace(-1.0, 1.0, n // 4, endpoint=False)
    one = np.ones_like(t)
    sq = np.concatenate(
        [
            np.stack([-one, -t], 1),
            np.stack([t, -one], 1),
            np.stack([one, t], 1),
            np.stack([-t, one], 1),
        ]
    )  # a square run counter-clockwise, starting at its corner (-1, 1)
    ring = mesh.vertices[center] + radius * (sq[:, :1] * e1 + sq[:, 1:] * e2)
    pts = closest_surface_points(mesh, ring)
    curve = densify_curve(mesh, SurfaceCurve(pts, closed=True, kind="boundary"))
    cut = cut_mesh(mesh, curve, closed=True, split=True)
    cm = cut.mesh
    fn = cm.face_neighbors
    rows = np.repeat(np.arange(cm.n_faces), 3)
    cols = fn.ravel()
    ok = cols >= 0
    g = sparse.csr_matrix((np.ones(ok.sum()), (rows[ok], cols[ok])), shape=(cm.n_faces,) * 2)
    _, lab = connected_components(g, directed=False)
    seed_face = cm.vertex_faces[1][cm.vertex_faces[0][center]]
    faces = np.flatnonzero(lab == lab[seed_face])
    corner_xyz = mesh.xyz(SurfacePoints(pts.face[:: n // 4], pts.bary[:: n // 4]))
    return _submesh_patch(cm, faces, corner_xyz, index)


def spring_state(patch: Patch, spring):
    """A building state (`meshfit.springs.state.State`) holding the points of ``spring``, a
    spring mesh of ``patch`` without feature curves (one section each way)."""
    from meshfit.springs.resample import _sides
    from meshfit.springs.state import State

    nu, nv = spring.shape
    sides = _sides(patch)
    breaks = {n: [0.0, float(sides.arcs[n][-1])] for n in sides.chains}
    state = State(patch.mesh, 0, sides, [], [], breaks, [nu - 1], [nv - 1])
    state.face = spring.points.face.copy()
    state.bary = spring.points.bary.copy()
    return state
