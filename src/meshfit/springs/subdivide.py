"""Spring mesh subdivision: FindMidPoint, sides resampled statically (sec. 5.6)."""

from __future__ import annotations

import numpy as np

from meshfit import tol
from meshfit._kernels import springs as _k
from meshfit.springs.planar import PlanarMap
from meshfit.springs.state import State

__all__ = ["subdivide"]

#: a greedy graph path longer than this many edges gives up (the walked guess is used)
_MAX_PATH = 2_000
_MAX_FACES = 10_000


def _mid(state: State, a: np.ndarray, b: np.ndarray, n_fair: int):
    mesh = state.mesh
    vfp, vf = mesh.vertex_faces
    indptr, indices = mesh.vertex_adjacency
    return _k.find_midpoints(
        mesh.vertices,
        mesh.faces,
        mesh.face_neighbors,
        vfp,
        vf,
        indptr,
        indices,
        state.on_boundary,
        state.face[a],
        state.bary[a],
        state.face[b],
        state.bary[b],
        n_fair,
        _MAX_PATH,
        tol.BARY_EPS,
        _MAX_FACES,
    )


def _mid_mapped(state: State, pmap, a: np.ndarray, b: np.ndarray):
    """Mid-points in the planar map: the image of the mean of the two points' parameters."""
    if isinstance(pmap, PlanarMap):
        uv = pmap.mid_uv(state.face, state.bary, a, b)
    else:
        uv = 0.5 * (
            pmap.uv_of(state.face[a], state.bary[a]) + pmap.uv_of(state.face[b], state.bary[b])
        )
    pts = pmap.locate(uv)
    return pts.face, pts.bary


def subdivide(state: State, *, n_fair: int = 3, pmap=None) -> None:
    """Double the spring mesh's intervals in both directions, in place.

    Old points keep their places at even grid indices. New points on the sides come from
    the static resampling of the sides, new points on feature curves from the mid-point in
    arc length on their curve (sec. 5.11.4), every other new point from FindMidPoint of its
    two neighbours along a row (then a column, then the cell centres from the new row
    points): a greedy graph path's middle vertex, then ``n_fair`` local fairness moves.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 5.6 (FindMidPoint), sec. 5.11.4.
    """
    nu, nv = state.nu, state.nv
    old_face = state.face.reshape(nu, nv)
    old_bary = state.bary.reshape(nu, nv, 3)
    old_v_lines = set(state.v_lines.tolist())
    old_u_lines = set(state.u_lines.tolist())
    state.counts_u = [2 * c for c in state.counts_u]
    state.counts_v = [2 * c for c in state.counts_v]
    state.level += 1
    NU, NV = state.nu, state.nv
    face = np.zeros((NU, NV), dtype=np.int64)
    bary = np.zeros((NU, NV, 3))
    face[::2, ::2] = old_face
    bary[::2, ::2] = old_bary
    for lst in (state.s_u, state.s_v):
        for k, s in enumerate(lst):
            t = np.empty(2 * len(s) - 1)
            t[::2] = s
            t[1::2] = 0.5 * (s[:-1] + s[1:])
            lst[k] = t
    state.face = face.ravel()
    state.bary = bary.reshape(-1, 3)
    state.set_boundary()
    state.set_feature_points()
    idx = np.arange(NU * NV).reshape(NU, NV)
    # row mid-points (2i + 1, 2j) on interior old rows that do not follow a v feature
    rows = [j for j in range(1, nv - 1) if j not in old_v_lines]
    if rows:
        r = 2 * np.array(rows)
        a = idx[0:-1:2][:, r].ravel()
        b = idx[2::2][:, r].ravel()
        f, bb = _mid(state, a, b, n_fair) if pmap is None else _mid_mapped(state, pmap, a, b)
        tgt = idx[1::2][:, r].ravel()
        state.face[tgt], state.bary[tgt] = f, bb
    cols = [i for i in range(1, nu - 1) if i not in old_u_lines]
    if cols:
        c = 2 * np.array(cols)
        a = idx[c][:, 0:-1:2].ravel()
        b = idx[c][:, 2::2].ravel()
        f, bb = _mid(state, a, b, n_fair) if pmap is None else _mid_mapped(state, pmap, a, b)
        tgt = idx[c][:, 1::2].ravel()
        state.face[tgt], state.bary[tgt] = f, bb
    a = idx[1::2, 0:-1:2].ravel()
    b = idx[1::2, 2::2].ravel()
    f, bb = _mid(state, a, b, n_fair) if pmap is None else _mid_mapped(state, pmap, a, b)
    tgt = idx[1::2, 1::2].ravel()
    state.face[tgt], state.bary[tgt] = f, bb
