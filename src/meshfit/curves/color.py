"""Colour (scalar-field) attraction for surface snakes (thesis sec. 3.8.2).

A scalar field on the mesh vertices (a colour channel, the colour magnitude or luminance, or
a curvature) gives a per-vertex gradient in the tangent plane (eq. 3.17). At a face point the
gradient is interpolated with the point's barycentric coordinates; only its component normal
to the curve within the surface is kept (the tangential part would only slide samples along
the curve and fight the arc-length force), and the result, weighted against the internal
forces (eq. 3.18), is the external force of :func:`meshfit.curves.snake.relax_snake`. The
gradient points toward higher values, so a snake is pushed up the field into the smooth,
zero-gradient interior of a painted band (its ridge); ``sign=-1`` seeks valleys instead.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from meshfit._validate import as_surface_points
from meshfit.errors import InputError
from meshfit.mesh import Mesh
from meshfit.types import SurfaceCurve

__all__ = ["color_force", "scalar_field", "vertex_gradients", "vertex_normals"]

FieldKind = Literal[
    "red", "green", "blue", "luminance", "magnitude", "gaussian_curvature", "mean_curvature"
]
_CHANNEL = {"red": 0, "green": 1, "blue": 2}


def vertex_normals(mesh: Mesh) -> NDArray[np.float64]:
    """(nv, 3) float64 unit vertex normals: area-weighted mean of the adjacent face normals
    (``mesh.vertex_normals``, cached on the mesh)."""
    return mesh.vertex_normals


def _angles_cot(mesh: Mesh):
    """Corner angles (nf, 3) and cotangents (nf, 3) of every face."""
    V, F = mesh.vertices, mesh.faces
    ang = np.empty(F.shape)
    cot = np.empty(F.shape)
    for k in range(3):
        p = V[F[:, k]]
        a = V[F[:, (k + 1) % 3]] - p
        b = V[F[:, (k + 2) % 3]] - p
        dot = np.einsum("ij,ij->i", a, b)
        crs = np.linalg.norm(np.cross(a, b), axis=1)
        ang[:, k] = np.arctan2(crs, dot)
        cot[:, k] = dot / np.where(crs > 0, crs, np.finfo(float).tiny)
    return ang, cot


def _mixed_areas(mesh: Mesh, ang, cot) -> NDArray[np.float64]:
    """Mixed Voronoi area per vertex (Meyer et al. 2003, fig. 4)."""
    V, F = mesh.vertices, mesh.faces
    area = np.zeros(mesh.n_vertices)
    fa = mesh.face_areas
    obtuse = (ang > np.pi / 2).any(axis=1)
    for k in range(3):
        i, j, l = F[:, k], F[:, (k + 1) % 3], F[:, (k + 2) % 3]
        eij = np.sum((V[j] - V[i]) ** 2, axis=1)
        eil = np.sum((V[l] - V[i]) ** 2, axis=1)
        vor = (eij * cot[:, (k + 2) % 3] + eil * cot[:, (k + 1) % 3]) / 8.0
        this = np.where(~obtuse, vor, np.where(ang[:, k] > np.pi / 2, fa / 2, fa / 4))
        np.add.at(area, i, this)
    return area


def scalar_field(mesh: Mesh, kind: FieldKind | ArrayLike) -> NDArray[np.float64]:
    """A scalar per vertex to attract snakes with.

    Parameters
    ----------
    mesh : Mesh
    kind : str or (nv,) float64
        ``"red"``, ``"green"``, ``"blue"``: one colour channel in [0, 1];
        ``"magnitude"``: length of the RGB vector over ``sqrt(3)``, in [0, 1];
        ``"luminance"``: Rec. 709 luma ``0.2126 R + 0.7152 G + 0.0722 B`` in [0, 1];
        ``"gaussian_curvature"``: angle defect over the mixed area, 1 / length**2;
        ``"mean_curvature"``: half the length of the cotangent Laplacian of the position over
        the mixed area, 1 / length, positive where the surface bends away from its normal
        (a sphere with outward normals has ``+1 / radius``);
        or any finite (nv,) array, returned as float64.

    Returns
    -------
    (nv,) float64

    Raises
    ------
    meshfit.errors.InputError
        Unknown kind; a colour field on a mesh without vertex colours; an array of the wrong
        length or with a non-finite value (the message names the vertex).

    References
    ----------
    .. [1] Krishnamurthy, "Fitting Smooth Surfaces to Dense Polygon Meshes", PhD thesis,
       Stanford 2000, sec. 3.8.2 (colour as a scalar: one channel or the colour magnitude;
       Gaussian curvature for creases and folds).
    .. [2] Meyer, Desbrun, Schroeder & Barr, "Discrete differential-geometry operators for
       triangulated 2-manifolds", VisMath 2002 (angle defect, mixed area, cotangent formula).
    """
    nv = mesh.n_vertices
    if isinstance(kind, str):
        if kind in _CHANNEL or kind in ("luminance", "magnitude"):
            if mesh.vertex_colors is None:
                raise InputError(
                    f"scalar field {kind!r} needs vertex colours, but mesh "
                    f"{mesh.name or '<unnamed>'} has none"
                )
            rgb = mesh.vertex_colors[:, :3].astype(np.float64) / 255.0
            if kind in _CHANNEL:
                return np.ascontiguousarray(rgb[:, _CHANNEL[kind]])
            if kind == "luminance":
                return rgb @ np.array([0.2126, 0.7152, 0.0722])
            return np.linalg.norm(rgb, axis=1) / np.sqrt(3.0)
        if kind in ("gaussian_curvature", "mean_curvature"):
            ang, cot = _angles_cot(mesh)
            area = _mixed_areas(mesh, ang, cot)
            area = np.where(area > 0, area, np.finfo(float).tiny)
            if kind == "gaussian_curvature":
                total = np.zeros(nv)
                for k in range(3):
                    np.add.at(total, mesh.faces[:, k], ang[:, k])
                full = np.full(nv, 2.0 * np.pi)
                loops = mesh.boundary_loops
                if loops:
                    full[np.concatenate(loops)] = np.pi
                return (full - total) / area
            V, F = mesh.vertices, mesh.faces
            lap = np.zeros((nv, 3))
            for k in range(3):  # edge (i, j) opposite corner k
                i, j = F[:, (k + 1) % 3], F[:, (k + 2) % 3]
                d = cot[:, k, None] * (V[i] - V[j])
                np.add.at(lap, i, d)
                np.add.at(lap, j, -d)
            hn = lap / (4.0 * area[:, None])  # = H n
            sign = np.sign(np.einsum("ij,ij->i", hn, vertex_normals(mesh)))
            return sign * np.linalg.norm(hn, axis=1)
        raise InputError(
            f"unknown scalar field kind {kind!r}: use one of red, green, blue, "
            "luminance, magnitude, gaussian_curvature, mean_curvature or an array"
        )
    a = np.asarray(kind, dtype=np.float64)
    if a.shape != (nv,):
        raise InputError(
            f"scalar field must have shape ({nv},) (one value per vertex), got {a.shape}"
        )
    bad = np.flatnonzero(~np.isfinite(a))
    if bad.size:
        raise InputError(f"scalar field is not finite at vertex {int(bad[0])}")
    return np.ascontiguousarray(a)


def vertex_gradients(
    mesh: Mesh, values: ArrayLike, *, method: Literal["least_squares", "thesis"] = "least_squares"
) -> NDArray[np.float64]:
    """Gradient of a vertex scalar field at every vertex, in the vertex's tangent plane.

    With ``d_j = S_j - S_0`` and ``e_j`` the one-ring edge vectors ``v_j - v_0`` projected to
    the tangent plane (normal: :func:`vertex_normals`), the thesis' gradient (eq. 3.17) is
    ``b = sum_j d_j e_j``. ``method="thesis"`` returns ``b``; ``"least_squares"`` (default)
    returns the ``g`` in the tangent plane minimising ``sum_j (g . e_j - d_j)**2``, i.e.
    ``(sum_j e_j e_j^T)^+ b``: eq. 3.17 normalised by the one-ring's structure tensor, so
    that a linear field has its exact gradient on any triangulation and the magnitude is in
    field units per length.

    Parameters
    ----------
    mesh : Mesh
    values : (nv,) float64
        Field per vertex (see :func:`scalar_field`).
    method : {"least_squares", "thesis"}, keyword-only

    Returns
    -------
    (nv, 3) float64
        Gradient per vertex, tangent to the surface at the vertex.

    Raises
    ------
    meshfit.errors.InputError
        ``values`` has the wrong length or a non-finite entry, or ``method`` is unknown.

    References
    ----------
    .. [1] Krishnamurthy, "Fitting Smooth Surfaces to Dense Polygon Meshes", PhD thesis,
       Stanford 2000, sec. 3.8.2, eq. 3.17.
    """
    s = scalar_field(mesh, values)
    if method not in ("least_squares", "thesis"):
        raise InputError(f"method must be 'least_squares' or 'thesis', got {method!r}")
    indptr, indices = mesh.vertex_adjacency
    nv = mesh.n_vertices
    owner = np.repeat(np.arange(nv), np.diff(indptr))
    nrm = vertex_normals(mesh)
    e = mesh.vertices[indices] - mesh.vertices[owner]
    e -= np.einsum("ij,ij->i", e, nrm[owner])[:, None] * nrm[owner]
    d = s[indices] - s[owner]
    b = np.zeros((nv, 3))
    np.add.at(b, owner, d[:, None] * e)
    if method == "thesis":
        return b
    a = np.zeros((nv, 3, 3))
    np.add.at(a, owner, e[:, :, None] * e[:, None, :])
    # solve in the tangent plane: add n n^T so the system is regular, then the answer has
    # no normal part (b is tangent)
    scale = np.trace(a, axis1=1, axis2=2)
    a += (np.where(scale > 0, scale, 1.0)[:, None, None]) * (nrm[:, :, None] * nrm[:, None, :])
    g = np.linalg.solve(a, b[:, :, None])[:, :, 0]
    g -= np.einsum("ij,ij->i", g, nrm)[:, None] * nrm
    return g


def color_force(
    mesh: Mesh,
    curve: SurfaceCurve,
    gradients: ArrayLike,
    *,
    weight: float = 1.0,
    sign: int = 1,
) -> NDArray[np.float64]:
    """Colour-attraction force on each sample of a snake (eq. 3.18's external term).

    The vertex gradients are interpolated at each face point with its barycentric
    coordinates, projected to the face's plane, and their component along the curve's
    tangent (central differences; one-sided at the ends of an open curve) is removed. The
    result is scaled to a displacement: ``weight * mesh.mean_edge_length * g / G`` with ``G``
    the largest vertex gradient length, so ``weight`` is directly comparable with the
    internal weights of :func:`~meshfit.curves.snake.relax_snake`.

    Parameters
    ----------
    mesh : Mesh
    curve : SurfaceCurve
        n samples.
    gradients : (nv, 3) float64
        From :func:`vertex_gradients`.
    weight : float, keyword-only
        Weight against the internal forces (>= 0).
    sign : {1, -1}, keyword-only
        +1 pushes samples up the field (onto ridges, into a bright band), -1 down it.

    Returns
    -------
    (n, 3) float64
        Force per sample, model units; pass as ``external`` to ``relax_snake`` (or a closure
        recomputing it every iteration: ``external=lambda c: color_force(mesh, c, g)``).

    Raises
    ------
    meshfit.errors.InputError
        Gradients of the wrong shape or not finite, curve not on the mesh, bad weight/sign.

    References
    ----------
    .. [1] Krishnamurthy, "Fitting Smooth Surfaces to Dense Polygon Meshes", PhD thesis,
       Stanford 2000, sec. 3.8.2, eq. 3.17-3.18 and fig. 3.15.
    """
    nv = mesh.n_vertices
    g = np.asarray(gradients, dtype=np.float64)
    if g.shape != (nv, 3):
        raise InputError(f"gradients must have shape ({nv}, 3), got {g.shape}")
    bad = np.flatnonzero(~np.isfinite(g).all(axis=1))
    if bad.size:
        raise InputError(f"gradients are not finite at vertex {int(bad[0])}")
    if not isinstance(curve, SurfaceCurve):
        raise InputError(f"curve must be a SurfaceCurve, got {type(curve).__name__}")
    pts = as_surface_points(mesh, curve.points, name="curve.points")
    try:
        weight = float(weight)
    except (TypeError, ValueError):
        raise InputError(f"weight must be a number, got {weight!r}") from None
    if not np.isfinite(weight) or weight < 0:
        raise InputError(f"weight must be a finite number >= 0, got {weight!r}")
    if sign not in (1, -1):
        raise InputError(f"sign must be 1 or -1, got {sign!r}")
    n = len(pts)
    if n == 0:
        return np.zeros((0, 3))
    big = float(np.linalg.norm(g, axis=1).max())
    if big == 0.0 or weight == 0.0:
        return np.zeros((n, 3))
    fg = np.einsum("ij,ijk->ik", pts.bary, g[mesh.faces[pts.face]])
    nrm = mesh.face_normals[pts.face]
    fg -= np.einsum("ij,ij->i", fg, nrm)[:, None] * nrm
    x = mesh.xyz(pts)
    if n >= 2:
        if curve.closed:
            t = np.roll(x, -1, axis=0) - np.roll(x, 1, axis=0)
        else:
            t = np.empty_like(x)
            t[1:-1] = x[2:] - x[:-2]
            t[0], t[-1] = x[1] - x[0], x[-1] - x[-2]
        t -= np.einsum("ij,ij->i", t, nrm)[:, None] * nrm
        tl = np.linalg.norm(t, axis=1, keepdims=True)
        t = np.divide(t, tl, out=np.zeros_like(t), where=tl > 0)
        fg -= np.einsum("ij,ij->i", fg, t)[:, None] * t
    return (sign * weight * mesh.mean_edge_length / big) * fg
