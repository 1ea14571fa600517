"""Coarse proxies of dense closed meshes: topology-preserving simplification by half-edge
collapses.

The sphere parameterization and the base mesh of a dense scan only need its coarse shape:
:func:`simplify_mesh` gives a closed mesh of the same genus whose vertices are a subset of
the input's (a half-edge collapse ``v -> u`` removes ``v`` and keeps ``u`` in place), with
triangles of bounded valence and shape.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from meshfit import errors
from meshfit._kernels import decimate as _k
from meshfit.mesh import Mesh

__all__ = ["SimplifiedMesh", "simplify_mesh"]

#: a collapse may turn a surviving face's normal by at most this angle (degrees)
MAX_NORMAL_TURN_DEG = 60.0
#: a collapse may not leave a vertex with more neighbours than this
MAX_VALENCE = 12
#: a surviving face must keep at least this quality (4 sqrt(3) area / sum of squared edge
#: lengths; 1 for an equilateral triangle) unless it was already worse
MIN_QUALITY = 0.15
#: passes of independent collapses before giving up on the target
_MAX_PASSES = 200


@dataclass(frozen=True, eq=False)
class SimplifiedMesh:
    """Result of :func:`simplify_mesh`.

    Attributes
    ----------
    mesh : Mesh
        The coarse mesh.
    vertex_parent : (nv_coarse,) int64
        Input vertex of each coarse vertex (same position).
    passes : int
        Collapse passes run.
    """

    mesh: Mesh
    vertex_parent: NDArray[np.int64]
    passes: int


def simplify_mesh(mesh: Mesh, target_faces: int) -> SimplifiedMesh:
    """Simplify a closed manifold mesh to about ``target_faces`` faces, same topology.

    Each pass collapses an independent set of edges, shortest first (half-edge collapses:
    the kept vertex does not move), under the link condition (so the genus and the
    manifoldness are kept), a valence cap, a bound on the turn of every surviving face's
    normal and a floor on its shape quality. Passes repeat until the face count reaches
    ``target_faces`` or no edge can be collapsed.

    Parameters
    ----------
    mesh : Mesh
        One closed manifold surface.
    target_faces : int
        Wanted face count (at least 20); the result has at most a few faces fewer, or more
        when the constraints stop the collapses first.

    Returns
    -------
    SimplifiedMesh

    Raises
    ------
    meshfit.errors.InputError
        ``target_faces`` below 20.
    meshfit.errors.TopologyError
        The mesh has boundary loops.

    References
    ----------
    .. [1] Hoppe, "Progressive meshes", SIGGRAPH 1996 (edge collapses);
       Dey, Edelsbrunner, Guha & Nekhayev, "Topology preserving edge contraction", 1999
       (the link condition).
    """
    target = int(target_faces)
    if target < 20:
        raise errors.InputError(f"target_faces must be at least 20, got {target_faces}")
    if not mesh.is_closed:
        raise errors.TopologyError(
            f"simplify_mesh needs a closed surface; {mesh.name or 'the mesh'} has boundary loops"
        )
    V = np.ascontiguousarray(mesh.vertices, dtype=np.float64)
    F = np.array(mesh.faces, dtype=np.int64, order="C")
    alive = np.ones(F.shape[0], dtype=np.bool_)
    kept = np.arange(V.shape[0], dtype=np.int64)
    n_alive = F.shape[0]
    min_cos = float(np.cos(np.radians(MAX_NORMAL_TURN_DEG)))
    passes = 0
    while n_alive > target and passes < _MAX_PASSES:
        # every collapse removes two faces
        want = (n_alive - target + 1) // 2
        done = _k.collapse_pass(V, F, alive, want, MAX_VALENCE, min_cos, MIN_QUALITY)
        passes += 1
        if done == 0:
            break
        n_alive -= 2 * done
        # drop the removed faces and vertices, keeping both orders (a monotone renumbering):
        # the next pass sees the same stars and breaks ties the same way, on fewer elements
        V, F, kept = _k.compact(V, F, alive, kept)
        alive = np.ones(F.shape[0], dtype=np.bool_)
    V, F, kept = _k.compact(V, F, alive, kept)
    coarse = Mesh(V, F, name=f"{mesh.name}_proxy" if mesh.name else "proxy")
    return SimplifiedMesh(coarse, kept, passes)
