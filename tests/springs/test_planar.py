"""The planar (mean-value) map of a patch to the unit square and the mapped spring mesh."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from meshfit import tol
from meshfit.errors import InputError
from meshfit.springs import SpringOptions, resample_patch
from meshfit.springs.planar import clear_map_cache, square_map
from meshfit.springs.resample import _sides

from ..conftest import real_mesh
from .patches import cap_map, cut_patch, param_patch, plane_map


def _signed_areas(uv, faces):
    a, b, c = uv[faces[:, 0]], uv[faces[:, 1]], uv[faces[:, 2]]
    return (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])


@pytest.mark.parametrize("which", ["cap", "igea"])
def test_square_map_is_a_bijection_onto_the_square(which):
    if which == "cap":
        patch = param_patch(cap_map(1.0, 0.6), 20, 20)
    else:
        patch = cut_patch(real_mesh("igea"), 1000, 0.02)
    sides = _sides(patch)
    pmap = square_map(patch.mesh, sides)
    uv = pmap.uv
    assert (uv >= -1e-12).all() and (uv <= 1 + 1e-12).all()
    # the sides lie on the square's sides, corners at its corners
    assert_allclose(uv[sides.chains["bottom"], 1], 0.0)
    assert_allclose(uv[sides.chains["top"], 1], 1.0)
    assert_allclose(uv[sides.chains["left"], 0], 0.0)
    assert_allclose(uv[sides.chains["right"], 0], 1.0)
    # no face turned over; only faces with three vertices on one side are flat
    area = _signed_areas(uv, patch.mesh.faces)
    assert area.min() >= -1e-15
    assert_allclose(0.5 * area.sum(), 1.0, rtol=1e-9)  # the faces tile the square once


def _square_map_oracle(mesh, sides):
    """The mean-value map by the textbook route: the full weight matrix, one spsolve."""
    import scipy.sparse as sp
    from scipy.sparse.linalg import spsolve

    V, F = mesh.vertices, mesh.faces
    n = mesh.n_vertices
    W = sp.lil_matrix((n, n))
    for f in range(len(F)):
        for c in range(3):
            i, j, k = F[f, c], F[f, (c + 1) % 3], F[f, (c + 2) % 3]
            eij, eik = V[j] - V[i], V[k] - V[i]
            lij, lik = np.linalg.norm(eij), np.linalg.norm(eik)
            theta = np.arccos(np.clip(eij @ eik / (lij * lik), -1.0, 1.0))
            W[i, j] += np.tan(theta / 2) / lij
            W[i, k] += np.tan(theta / 2) / lik
    W = W.tocsr()
    uv = np.zeros((n, 2))
    fixed = np.zeros(n, dtype=bool)
    for name, axis, const in [("bottom", 0, 0), ("top", 0, 1), ("left", 1, 0), ("right", 1, 1)]:
        arc = sides.arcs[name]
        uv[sides.chains[name], axis] = arc / arc[-1]
        uv[sides.chains[name], 1 - axis] = const
        fixed[sides.chains[name]] = True
    free, fix = np.flatnonzero(~fixed), np.flatnonzero(fixed)
    A = sp.diags(np.asarray(W.sum(axis=1)).ravel()[free]) - W[free][:, free]
    uv[free] = spsolve(A.tocsc(), W[free][:, fix] @ uv[fix])
    return uv


@pytest.mark.parametrize("which", ["cap", "igea"])
def test_square_map_matches_the_plain_solve(which):
    if which == "cap":
        patch = param_patch(cap_map(1.0, 0.6), 20, 20)
    else:
        patch = cut_patch(real_mesh("igea"), 1000, 0.02)
    sides = _sides(patch)
    clear_map_cache()
    got = square_map(patch.mesh, sides).uv
    assert_allclose(got, _square_map_oracle(patch.mesh, sides), rtol=0, atol=tol.TEST_ATOL)


def test_square_map_is_kept_per_patch_mesh():
    patch = param_patch(cap_map(1.0, 0.6), 12, 10)
    sides = _sides(patch)
    clear_map_cache()
    a = square_map(patch.mesh, sides)
    assert square_map(patch.mesh, _sides(patch)).uv is a.uv  # equal sides, new object: kept
    with pytest.raises(ValueError, match="read-only"):
        a.uv[0, 0] = 0.5  # shared between callers: nobody may change it
    other = param_patch(cap_map(1.0, 0.6), 12, 10)  # equal arrays, another mesh object
    b = square_map(other.mesh, _sides(other))
    assert b.uv is not a.uv
    assert_allclose(b.uv, a.uv, rtol=0, atol=tol.TEST_ATOL)
    clear_map_cache()
    c = square_map(patch.mesh, sides)
    assert c.uv is not a.uv
    np.testing.assert_array_equal(c.uv, a.uv)


def test_a_kept_square_map_does_not_keep_its_mesh_alive():
    # the cache is keyed weakly by the mesh: a fit's patch meshes (as large together as
    # the scan) must go when the fit drops them, not stay for the process's lifetime
    import gc
    import weakref

    patch = param_patch(cap_map(1.0, 0.6), 12, 10)
    square_map(patch.mesh, _sides(patch), balanced=True)
    gone = weakref.ref(patch.mesh)
    del patch
    gc.collect()
    assert gone() is None


def test_locate_inverts_the_map():
    patch = param_patch(cap_map(1.0, 0.6), 20, 20)
    pmap = square_map(patch.mesh, _sides(patch))
    q = np.random.default_rng(1).uniform(0.0, 1.0, (500, 2))
    pts = pmap.locate(q)
    assert (pts.bary >= 0).all()
    assert_allclose(pmap.uv_of(pts.face, pts.bary), q, atol=1e-12)


def test_plane_grid_is_the_same_from_either_start():
    plane = param_patch(plane_map(2.0, 1.0), 40, 20)
    a = resample_patch(plane, SpringOptions(level=2, fidelity=False))
    b = resample_patch(
        plane, SpringOptions(level=2, init="dijkstra", midpoints="findmid", fidelity=False)
    )
    nv = a.final.shape[1]
    assert a.final.shape == b.final.shape
    assert_allclose(a.final.xyz, b.final.xyz, atol=1e-2 / (nv - 1))
    assert all(m["folded"] == 0 for m in a.metrics + b.metrics)


def test_start_options_are_checked():
    plane = param_patch(plane_map(2.0, 1.0), 8, 4)
    with pytest.raises(InputError, match="init"):
        resample_patch(plane, SpringOptions(init="tutte"))
    with pytest.raises(InputError, match="midpoints"):
        resample_patch(plane, SpringOptions(midpoints="graph"))


def test_chord_positions_even_out_the_chords_of_a_bent_side():
    from meshfit.springs.state import chord_positions, section_positions

    # an L-shaped polyline: equal arc lengths put a short chord across the bend
    t = np.linspace(0.0, 1.0, 201)
    xyz = np.concatenate([np.column_stack([t, 0 * t, 0 * t]), [[1.0, s, 0.0] for s in t[1:]]])
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(xyz, axis=0), axis=1))])
    breaks, counts = [0.0, 1.3, 2.0], [5, 2]
    pos = chord_positions(xyz, arc, breaks, counts, rounds=200)
    ends = section_positions(breaks, counts)[[0, 5, 7]]
    assert_allclose(pos[[0, 5, 7]], ends)  # section ends stay
    P = np.column_stack([np.interp(pos, arc, xyz[:, d]) for d in range(3)])
    c = np.linalg.norm(np.diff(P, axis=0), axis=1)
    assert np.ptp(c[:5]) < 1e-6 * c[:5].mean()  # equal within the first section
    plain = np.column_stack(
        [np.interp(section_positions(breaks, counts), arc, xyz[:, d]) for d in range(3)]
    )
    c0 = np.linalg.norm(np.diff(plain, axis=0), axis=1)
    assert np.ptp(c0[:5]) > 0.1 * c0[:5].mean()  # the arc-length spacing was uneven


def test_side_spacing_option():
    plane = param_patch(plane_map(2.0, 1.0), 8, 4)
    with pytest.raises(InputError, match="side_spacing"):
        resample_patch(plane, SpringOptions(side_spacing="even"))
    a = resample_patch(plane, SpringOptions(level=1, side_spacing="arc", fidelity=False))
    assert a.metrics[-1]["folded"] == 0


# --- the interior solve: kernels against tests/reference/planar.py, multigrid against LU


def _interior(which):
    from meshfit.springs import planar

    if which == "cap":
        patch = param_patch(cap_map(1.0, 0.6), 30, 30)
    else:
        patch = cut_patch(real_mesh("igea"), 1000, 0.02)
    mesh, sides = patch.mesh, _sides(patch)
    uv = np.zeros((mesh.n_vertices, 2))
    fixed = np.zeros(mesh.n_vertices, dtype=bool)
    for name, axis, const in [("bottom", 0, 0), ("top", 0, 1), ("left", 1, 0), ("right", 1, 1)]:
        arc = sides.arcs[name]
        uv[sides.chains[name], axis] = arc / arc[-1]
        uv[sides.chains[name], 1 - axis] = const
        fixed[sides.chains[name]] = True
    free = np.flatnonzero(~fixed)
    return planar, mesh, uv, fixed, free


@pytest.mark.parametrize("which", ["cap", "igea"])
def test_interior_system_matches_the_oracle(which):
    from ..reference import planar as ref

    planar, mesh, uv, fixed, free = _interior(which)
    A, rhs = planar._interior_system(mesh, uv, fixed, free)
    at = np.full(mesh.n_vertices, -1)
    at[free] = np.arange(free.size)
    floor = tol.BARY_EPS * mesh.mean_edge_length
    A_ref, rhs_ref = ref.mean_value_system(mesh.vertices, mesh.faces, at, uv, floor, tol.BARY_EPS)
    scale = np.abs(A_ref).max()
    # the kernel and the oracle reach the weights by different formulas: igea's patch has
    # entries near 1e10 (a sliver left by the cut, angles near pi) that differ by up to
    # 1.3e-12 of the largest as the cut's rounding varies (the ring's closest points on
    # shared edges and vertices), and by 1.8e-8 of themselves on CPUs where numpy fuses
    # multiply-adds (the half-angle tangents of a sliver amplify the last bit)
    assert_allclose(A.toarray(), A_ref, rtol=1e-7, atol=4e-12 * scale)
    assert_allclose(rhs, rhs_ref, rtol=1e-7, atol=4e-12 * scale)
    # rows sorted and unique: what the Gauss-Seidel and residual kernels expect
    for i in range(A.shape[0]):
        cols = A.indices[A.indptr[i] : A.indptr[i + 1]]
        assert (np.diff(cols) > 0).all()


@pytest.mark.parametrize("backward", [False, True])
def test_gauss_seidel_matches_the_oracle(backward):
    from meshfit._kernels import planar as kp

    from ..reference import planar as ref

    planar, mesh, uv, fixed, free = _interior("cap")
    A, rhs = planar._interior_system(mesh, uv, fixed, free)
    x0 = np.random.default_rng(0).random(rhs.shape)
    x = x0.copy()
    kp.gauss_seidel(A.indptr, A.indices, A.data, x, rhs, 2, backward)
    assert_allclose(x, ref.gauss_seidel(A.toarray(), x0, rhs, 2, backward), atol=1e-12)
    r = np.empty_like(x)
    worst = kp.scaled_residual(A.indptr, A.indices, A.data, x, rhs, r)
    assert_allclose(r, rhs - A @ x, atol=1e-9 * np.abs(rhs).max())
    assert_allclose(worst, np.abs(r / A.diagonal()[:, None]).max(), rtol=1e-12)


def test_reweighted_interior_system_matches_the_oracle():
    from ..reference import planar as ref

    planar, mesh, uv, fixed, free = _interior("cap")
    scale = np.random.default_rng(3).uniform(0.2, 5.0, mesh.n_vertices)
    A, rhs = planar._interior_system(mesh, uv, fixed, free, scale)
    at = np.full(mesh.n_vertices, -1)
    at[free] = np.arange(free.size)
    floor = tol.BARY_EPS * mesh.mean_edge_length
    A_ref, rhs_ref = ref.mean_value_system(
        mesh.vertices, mesh.faces, at, uv, floor, tol.BARY_EPS, scale
    )
    big = np.abs(A_ref).max()
    assert_allclose(A.toarray(), A_ref, rtol=0, atol=4e-12 * big)
    assert_allclose(rhs, rhs_ref, rtol=0, atol=4e-12 * big)
    # the weights differ from the plain system's
    A0, _ = planar._interior_system(mesh, uv, fixed, free)
    assert np.abs(A.toarray() - A0.toarray()).max() > 0.1 * big


def test_balanced_map_spreads_a_squeezed_patch_and_stays_a_bijection():
    from meshfit.layout import extract_patches, load_layout
    from meshfit.springs import planar

    from ..conftest import ROOT

    mesh = real_mesh("spot")
    # spot's near-triangular patch 1: the mean-value map squeezes a third of it into a tenth
    # of the square
    patch = extract_patches(mesh, load_layout(ROOT / "examples" / "layouts" / "spot.json", mesh))[1]
    sides = _sides(patch)
    plain = square_map(patch.mesh, sides)
    balanced = square_map(patch.mesh, sides, balanced=True)
    assert square_map(patch.mesh, sides, balanced=True).uv is balanced.uv  # kept per mesh
    assert balanced is not plain
    _, before = planar._vertex_stretch(patch.mesh, plain.uv)
    _, after = planar._vertex_stretch(patch.mesh, balanced.uv)
    assert after < 0.8 * before
    area = _signed_areas(balanced.uv, patch.mesh.faces)
    assert area.min() >= -1e-15
    assert_allclose(0.5 * area.sum(), 1.0, rtol=1e-9)
    # the sides keep their arc-length parameters
    for name in ("bottom", "right", "top", "left"):
        assert_allclose(balanced.uv[sides.chains[name]], plain.uv[sides.chains[name]], atol=0)


def test_aggregates_cover_every_unknown_once():
    from meshfit._kernels import planar as kp

    planar, mesh, uv, fixed, free = _interior("igea")
    A, _ = planar._interior_system(mesh, uv, fixed, free)
    agg, na = kp.aggregate(A.indptr, A.indices, A.data, planar._STRENGTH)
    assert agg.shape == (A.shape[0],)
    assert agg.min() == 0 and agg.max() == na - 1
    assert (np.bincount(agg, minlength=na) > 0).all()
    assert na < A.shape[0] / 3  # the hierarchy coarsens


def test_dense_lu_solves():
    from meshfit._kernels import planar as kp

    rng = np.random.default_rng(1)
    a = rng.random((40, 40)) + np.eye(40)
    b = rng.random((40, 2))
    lu, piv = kp.dense_lu(a)
    assert_allclose(kp.dense_lu_solve(lu, piv, b), np.linalg.solve(a, b), atol=1e-10)


@pytest.mark.parametrize("which", ["cap", "igea"])
def test_multigrid_solve_matches_the_direct_solve(which, monkeypatch):
    planar, mesh, uv, fixed, free = _interior(which)
    assert free.size > planar._COARSEST  # the multigrid path, not the fallback
    A, rhs = planar._interior_system(mesh, uv, fixed, free)
    x = planar._gmres(A, rhs, planar._Multigrid(A))
    assert x is not None
    want = planar._direct_solve(A, rhs)
    assert_allclose(x, want, rtol=0, atol=tol.TEST_ATOL)
    r = rhs - A @ x
    assert np.abs(r / A.diagonal()[:, None]).max() <= planar._SOLVE_TOL
    # above the direct solve's size the iterative one answers
    monkeypatch.setattr(planar, "_DIRECT_MAX", 0)
    assert_allclose(planar._solve_interior(mesh, uv, fixed, free), x, rtol=0, atol=0)
    # no convergence within the cap: the direct solve answers
    monkeypatch.setattr(planar, "_MAX_ITER", 0)
    assert planar._gmres(A, rhs, planar._Multigrid(A)) is None
    assert_allclose(planar._solve_interior(mesh, uv, fixed, free), want, rtol=0, atol=1e-14)


@pytest.mark.parametrize("which", ["cap", "igea"])
def test_a_warm_started_solve_reaches_the_same_tolerance_in_fewer_iterations(which, monkeypatch):
    planar, mesh, uv, fixed, free = _interior(which)
    A, rhs = planar._interior_system(mesh, uv, fixed, free)
    mg = planar._Multigrid(A)
    want = planar._direct_solve(A, rhs)
    cold = planar._gmres(A, rhs, mg)
    # a guess near the answer (as a reweighted round starts from the last map)
    rng = np.random.default_rng(3)
    guess = want + 1e-6 * rng.standard_normal(want.shape)
    warm = planar._gmres(A, rhs, mg, guess)
    assert warm is not None and cold is not None
    assert_allclose(warm, want, rtol=0, atol=tol.TEST_ATOL)
    assert np.abs((rhs - A @ warm) / A.diagonal()[:, None]).max() <= planar._SOLVE_TOL
    assert guess.flags.writeable and not np.shares_memory(warm, guess)  # the guess is kept
    # iterations counted by the preconditioner's cycles from the top level
    calls = {"n": 0}
    cycle = planar._Multigrid.cycle

    def counted(self, b, k=0):
        calls["n"] += k == 0
        return cycle(self, b, k)

    monkeypatch.setattr(planar._Multigrid, "cycle", counted)
    planar._gmres(A, rhs, mg)
    from_zero, calls["n"] = calls["n"], 0
    planar._gmres(A, rhs, mg, guess)
    assert calls["n"] < from_zero


def test_the_balanced_map_solves_the_plain_map_once(monkeypatch):
    from meshfit.springs import planar

    patch = cut_patch(real_mesh("igea"), 1000, 0.02)
    sides = _sides(patch)
    clear_map_cache()
    # the plain map and its balance, computed here without the cache
    whole = planar._square_map(patch.mesh, sides)
    _, fixed = planar._boundary(patch.mesh.n_vertices, sides)
    want = planar._balanced(patch.mesh, whole.uv.copy(), fixed, np.flatnonzero(~fixed))
    scales = []
    solve = planar._solve_interior

    def counted(mesh, uv, fixed, free, scale=None, guess=None):
        scales.append(scale)
        return solve(mesh, uv, fixed, free, scale, guess)

    monkeypatch.setattr(planar, "_solve_interior", counted)
    plain = square_map(patch.mesh, sides)
    balanced = square_map(patch.mesh, sides, balanced=True)
    assert sum(s is None for s in scales) == 1  # the plain system, solved once for both
    assert len(scales) >= 2  # and at least one reweighted round
    assert_allclose(plain.uv, whole.uv, rtol=0, atol=0)
    assert_allclose(balanced.uv, want, rtol=0, atol=0)


def test_a_solve_that_stalls_at_the_floor_keeps_its_answer(monkeypatch):
    planar, mesh, uv, fixed, free = _interior("igea")
    A, rhs = planar._interior_system(mesh, uv, fixed, free)
    mg = planar._Multigrid(A)
    want = planar._direct_solve(A, rhs)
    # a target below what float64 reaches, and iterations enough to get there: the
    # restarts stall near round-off
    monkeypatch.setattr(planar, "_SOLVE_TOL", 1e-30)
    monkeypatch.setattr(planar, "_MAX_ITER", 1000)
    restarts = []
    residual = planar._kp.scaled_residual

    def counted(ip, ix, d, x, b, r):
        w = residual(ip, ix, d, x, b, r)
        if b is rhs:
            restarts.append(w)
        return w

    monkeypatch.setattr(planar._kp, "scaled_residual", counted)
    x = planar._gmres(A, rhs, mg)
    assert x is not None and restarts[-1] <= planar._FLOOR_TOL
    assert restarts[-1] > 0.5 * restarts[-2]  # it stopped where a restart no longer helped
    assert len(restarts) < 10  # not the whole budget
    assert_allclose(x, want, rtol=0, atol=tol.TEST_ATOL)
    # stalled above the floor: the direct solve answers
    monkeypatch.setattr(planar, "_FLOOR_TOL", 1e-30)
    assert planar._gmres(A, rhs, mg) is None
