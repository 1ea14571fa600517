"""Analytic test shapes with known answers (sphere, plane, cylinder, torus)."""

from __future__ import annotations

import numpy as np

from meshfit.mesh import Mesh


def icosphere(subdivisions: int = 3, radius: float = 1.0) -> Mesh:
    """Closed genus-0 sphere of ``20 * 4**subdivisions`` faces."""
    import trimesh

    s = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    return Mesh(np.asarray(s.vertices), np.asarray(s.faces), name=f"icosphere{subdivisions}")


def plane(n: int = 20, size: float = 1.0, *, jitter: float = 0.3, seed: int = 0) -> Mesh:
    """Irregularly triangulated flat square ``[0, size]^2`` in z = 0 (a disk, one boundary loop)."""
    rng = np.random.default_rng(seed)
    h = size / n
    u, v = np.meshgrid(np.arange(n + 1) * h, np.arange(n + 1) * h, indexing="ij")
    xy = np.stack([u.ravel(), v.ravel()], axis=1)
    inner = ((u > 0) & (u < size - 1e-12) & (v > 0) & (v < size - 1e-12)).ravel()
    xy[inner] += rng.uniform(-jitter * h, jitter * h, size=(int(inner.sum()), 2))
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    a, b, c, d = (
        idx[:-1, :-1].ravel(),
        idx[1:, :-1].ravel(),
        idx[1:, 1:].ravel(),
        idx[:-1, 1:].ravel(),
    )
    flip = rng.random(a.size) < 0.5
    f1 = np.where(flip[:, None], np.stack([a, b, c], 1), np.stack([a, b, d], 1))
    f2 = np.where(flip[:, None], np.stack([a, c, d], 1), np.stack([b, c, d], 1))
    faces = np.concatenate([f1, f2])
    verts = np.concatenate([xy, np.zeros((xy.shape[0], 1))], axis=1)
    return Mesh(verts, faces, name=f"plane{n}")


def cylinder(
    n_around: int = 32, n_along: int = 16, radius: float = 1.0, height: float = 2.0
) -> Mesh:
    """Open tube (two boundary loops), axis z, outward normals."""
    t = np.linspace(0, 2 * np.pi, n_around, endpoint=False)
    z = np.linspace(0, height, n_along + 1)
    T, Z = np.meshgrid(t, z, indexing="ij")
    verts = np.stack([radius * np.cos(T).ravel(), radius * np.sin(T).ravel(), Z.ravel()], axis=1)
    idx = np.arange(n_around * (n_along + 1)).reshape(n_around, n_along + 1)
    nxt = np.roll(idx, -1, axis=0)
    a, b, c, d = idx[:, :-1].ravel(), nxt[:, :-1].ravel(), nxt[:, 1:].ravel(), idx[:, 1:].ravel()
    faces = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return Mesh(verts, faces, name="cylinder")


def torus(n_major: int = 48, n_minor: int = 24, major: float = 1.0, minor: float = 0.35) -> Mesh:
    """Closed genus-1 torus."""
    u = np.linspace(0, 2 * np.pi, n_major, endpoint=False)
    v = np.linspace(0, 2 * np.pi, n_minor, endpoint=False)
    U, V = np.meshgrid(u, v, indexing="ij")
    r = major + minor * np.cos(V)
    verts = np.stack(
        [(r * np.cos(U)).ravel(), (r * np.sin(U)).ravel(), (minor * np.sin(V)).ravel()], 1
    )
    idx = np.arange(n_major * n_minor).reshape(n_major, n_minor)
    nu = np.roll(idx, -1, axis=0)
    nv = np.roll(idx, -1, axis=1)
    nuv = np.roll(nu, -1, axis=1)
    faces = np.concatenate(
        [
            np.stack([idx.ravel(), nu.ravel(), nuv.ravel()], 1),
            np.stack([idx.ravel(), nuv.ravel(), nv.ravel()], 1),
        ]
    )
    return Mesh(verts, faces, name="torus")


def _from_manifold(m, name: str) -> Mesh:
    mesh = m.to_mesh()
    verts = np.asarray(mesh.vert_properties, dtype=np.float64)[:, :3]
    return Mesh(verts, np.asarray(mesh.tri_verts, dtype=np.int64), name=name)


def tori(genus: int, *, edge: float = 0.09, minor: float = 0.32, blend: float = 0.12) -> Mesh:
    """Closed smooth surface of ``genus`` handles: tori in a row blended by a smooth minimum
    (marching tetrahedra of manifold3d on the blended distance field)."""
    import manifold3d as m3

    R = 1.0
    centres = [2.0 * R * (k - (genus - 1) / 2.0) * 0.8 for k in range(genus)]

    def sdf(x: float, y: float, z: float) -> float:
        d = None
        for cx in centres:
            q = np.hypot(np.hypot(x - cx, y) - R, z) - minor
            if d is None:
                d = q
            else:  # polynomial smooth minimum
                h = max(blend - abs(d - q), 0.0) / blend
                d = min(d, q) - h * h * blend / 4.0
        return -float(d)  # positive inside

    half = abs(centres[0]) + R + minor + 0.2
    bounds = [-half, -R - minor - 0.2, -minor - 0.2, half, R + minor + 0.2, minor + 0.2]
    return _from_manifold(m3.Manifold.level_set(sdf, bounds, edge), f"genus{genus}")


def box_with_holes(holes: int = 3, *, segments: int = 24) -> Mesh:
    """A genus-``holes`` CAD-like solid with sharp edges: a slab with round through holes."""
    import manifold3d as m3

    width = 1.2 * holes
    slab = m3.Manifold.cube([width, 1.2, 0.5], center=True)
    for k in range(holes):
        x = 1.2 * (k - (holes - 1) / 2.0)
        hole = m3.Manifold.cylinder(1.0, 0.3, 0.3, segments, center=True).translate([x, 0, 0])
        slab = slab - hole
    return _from_manifold(slab.refine_to_length(0.06), f"slab{holes}")


def cad_part(split: int = 2) -> Mesh:
    """A genus-2 machined part as a CAD program tessellates it: a block with two round
    through holes and a round boss, the boolean's own triangles (fans of needles across the
    flat faces, strips along the cylinders) with every edge split into ``split`` pieces."""
    import manifold3d as m3

    block = m3.Manifold.cube([4.0, 2.0, 1.0], center=True)
    block -= m3.Manifold.cylinder(3.0, 0.4, 0.4, 48, center=True).translate([-1.0, 0, 0])
    block -= m3.Manifold.cylinder(3.0, 0.3, 0.3, 48, center=True).translate([1.2, 0, 0])
    block += m3.Manifold.cylinder(0.8, 0.5, 0.5, 48).translate([0.2, 0, 0.5])
    return _from_manifold(block.refine(split) if split > 1 else block, "cad_part")


def joined_solids() -> Mesh:
    """Two solids joined as a modeller's boolean union tessellates them: a sphere and a
    leaning cone, whose seam turns by 30 to 100 degrees round it (the boolean's own
    triangles, needles along the seam)."""
    import manifold3d as m3

    body = m3.Manifold.sphere(1.0, 64)
    leg = m3.Manifold.cylinder(1.8, 0.28, 0.2, 40).rotate([180, 0, 0]).translate([0.45, 0, -0.6])
    return _from_manifold(body + leg, "joined_solids")


def cube(*, rounded: float = 0.0, n: int = 12) -> Mesh:
    """Closed cube of side 2, ``n`` x ``n`` quads a face (each split in two); with
    ``rounded`` > 0 its edges and corners are rounded with that radius (the points pushed
    onto the rounded box), else its 12 edges are sharp."""
    t = np.linspace(-1.0, 1.0, n + 1)
    verts, faces = [], []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            U, V = np.meshgrid(t, t, indexing="ij")
            p = np.zeros((n + 1, n + 1, 3))
            a, b = (axis + 1) % 3, (axis + 2) % 3
            p[..., axis] = sign
            p[..., a], p[..., b] = U, V
            base = len(verts) and sum(len(x) for x in verts)
            verts.append(p.reshape(-1, 3))
            idx = base + np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
            q = np.stack(
                [
                    idx[:-1, :-1].ravel(),
                    idx[1:, :-1].ravel(),
                    idx[1:, 1:].ravel(),
                    idx[:-1, 1:].ravel(),
                ],
                1,
            )
            if sign < 0:
                q = q[:, ::-1]
            faces += [q[:, [0, 1, 2]], q[:, [0, 2, 3]]]
    V = np.concatenate(verts)
    F = np.concatenate(faces)
    # weld the shared edge points of the six faces
    key = np.round(V * 1e6).astype(np.int64)
    _, first, inv = np.unique(key, axis=0, return_index=True, return_inverse=True)
    V, F = V[first], inv.reshape(-1)[F]
    if rounded > 0.0:
        inner = np.clip(V, -1.0 + rounded, 1.0 - rounded)
        d = V - inner
        nd = np.linalg.norm(d, axis=1, keepdims=True)
        V = np.where(nd > 0, inner + rounded * d / np.maximum(nd, 1e-300), V)
    return Mesh(V, F, name="rounded_cube" if rounded else "cube")


def hemisphere(subdivisions: int = 3) -> Mesh:
    """Open half sphere (z >= 0), one boundary loop."""
    s = icosphere(subdivisions)
    keep = s.vertices[s.faces].mean(axis=1)[:, 2] > 0.0
    f = s.faces[keep]
    used, inv = np.unique(f, return_inverse=True)
    return Mesh(s.vertices[used], inv.reshape(-1, 3), name="hemisphere")


def disk(n: int = 24) -> Mesh:
    """Flat round disk of radius 1: the jittered plane mapped onto it by the elliptical grid
    mapping (a smooth bijection of the square onto the disk, so no triangle folds)."""
    p = plane(n, 2.0)
    x, y = p.vertices[:, 0] - 1.0, p.vertices[:, 1] - 1.0
    u = x * np.sqrt(1.0 - y * y / 2.0)
    v = y * np.sqrt(1.0 - x * x / 2.0)
    return Mesh(np.column_stack([u, v, np.zeros(len(u))]), p.faces, name="disk")


def two_spheres() -> Mesh:
    """Two disjoint closed spheres of different sizes."""
    a, b = icosphere(3), icosphere(2, radius=0.6)
    v = np.vstack([a.vertices, b.vertices + np.array([3.0, 0.0, 0.0])])
    f = np.vstack([a.faces, b.faces + a.n_vertices])
    return Mesh(v, f, name="two_spheres")


def debris(specks: int = 60, flakes: int = 20, *, seed: int = 0) -> Mesh:
    """A sphere amid ``specks`` tiny closed icosahedra and ``flakes`` lone triangles: the
    floating bits a raw scan keeps."""
    rng = np.random.default_rng(seed)
    body = icosphere(3)
    ico = icosphere(0, radius=0.01)
    vs, fs, n = [body.vertices], [body.faces], body.n_vertices
    for _ in range(specks):
        vs.append(ico.vertices + rng.uniform(-2.0, 2.0, 3))
        fs.append(ico.faces + n)
        n += ico.n_vertices
    for _ in range(flakes):
        vs.append(rng.uniform(-2.0, 2.0, 3) + rng.normal(0.0, 0.01, (3, 3)))
        fs.append(np.array([[n, n + 1, n + 2]]))
        n += 3
    return Mesh(np.vstack(vs), np.vstack(fs), name="debris")


def dirty_sphere() -> tuple[np.ndarray, np.ndarray]:
    """Arrays of a sphere with a fin (a non-manifold edge), duplicate faces and unreferenced
    vertices: what a raw range-scan merge holds."""
    s = icosphere(3)
    v = np.vstack([s.vertices, [[5.0, 5.0, 5.0], [6.0, 5.0, 5.0]]])  # two unreferenced
    f = np.asarray(s.faces)
    e0, e1 = f[0, 0], f[0, 1]
    tip = len(v)
    v = np.vstack([v, (v[e0] + v[e1]) / 2.0 * 1.3])
    fin = [[e1, e0, tip]]
    return v, np.vstack([f, f[5:8], fin])


def spiky(arms: int = 8, *, edge: float = 0.05, length: float = 1.6, seed: int = 0) -> Mesh:
    """Closed genus-0 body with ``arms`` long protrusions (capsules from the centre, blended
    by a smooth minimum): a statue's limbs, ears and tails in one shape."""
    import manifold3d as m3

    rng = np.random.default_rng(seed)
    dirs = rng.normal(size=(arms, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    radii = 0.12 + 0.08 * rng.random(arms)

    def sdf(x: float, y: float, z: float) -> float:
        p = np.array([x, y, z])
        d = np.linalg.norm(p) - 0.6
        for a, r in zip(dirs, radii, strict=True):
            t = np.clip(p @ a, 0.0, length)
            q = np.linalg.norm(p - t * a) - r
            h = max(0.15 - abs(d - q), 0.0) / 0.15
            d = min(d, q) - h * h * 0.15 / 4.0
        return -float(d)

    b = length + 0.4
    return _from_manifold(m3.Manifold.level_set(sdf, [-b, -b, -b, b, b, b], edge), "spiky")


def quadruped(*, segments: int = 48) -> Mesh:
    """Closed genus-0 animal: a body on four long legs, a neck and a head with two thin
    ears, a tail (the union of capsules, each the hull of two spheres). Its legs are 15
    radii long."""
    import manifold3d as m3

    parts = [  # (from, to, radius)
        ((-0.7, 0, 0), (0.7, 0, 0), 0.35),
        ((-0.55, 0.18, -0.1), (-0.6, 0.2, -1.3), 0.08),
        ((-0.55, -0.18, -0.1), (-0.6, -0.2, -1.3), 0.08),
        ((0.55, 0.18, -0.1), (0.6, 0.2, -1.3), 0.08),
        ((0.55, -0.18, -0.1), (0.6, -0.2, -1.3), 0.08),
        ((0.7, 0, 0.1), (1.1, 0, 0.8), 0.13),
        ((1.1, 0, 0.8), (1.5, 0, 0.65), 0.12),
        ((1.1, 0.07, 0.9), (1.05, 0.1, 1.2), 0.035),
        ((1.1, -0.07, 0.9), (1.05, -0.1, 1.2), 0.035),
        ((-0.8, 0, 0.1), (-1.4, 0, -0.4), 0.04),
    ]
    body = None
    for a, b, r in parts:
        ball = m3.Manifold.sphere(r, segments)
        capsule = m3.Manifold.batch_hull([ball.translate(a), ball.translate(b)])
        body = capsule if body is None else body + capsule
    return _from_manifold(body, "quadruped")
