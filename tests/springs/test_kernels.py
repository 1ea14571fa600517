"""Spring-mesh kernels against their slow oracles (tests/reference/springs.py)."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from meshfit import tol
from meshfit._kernels import springs as K
from meshfit.springs import FREE, SpringOptions, resample_patch
from meshfit.types import SurfacePoints

from ..conftest import real_mesh
from ..reference import springs as ref
from .patches import cap_map, cut_patch, param_patch


@pytest.fixture(scope="module")
def patches():
    return {
        "cap": param_patch(cap_map(), 16, 16),
        "spot": cut_patch(real_mesh("spot"), 100, 0.25),
    }


@pytest.mark.parametrize(
    "tangent,guard,lazy,fold",
    [
        (False, False, 0.0, False),
        (True, False, 0.0, False),
        (False, True, 0.0, False),
        (True, True, 0.02, False),
        (True, True, 0.02, True),
    ],
)
@pytest.mark.parametrize("name", ["cap", "spot"])
def test_relax_sweeps_matches_oracle(patches, name, tangent, guard, lazy, fold, rng):
    patch = patches[name]
    mesh = patch.mesh
    sm = resample_patch(patch, SpringOptions(level=1, max_iter=1, metrics=False)).final
    nu, nv = sm.shape
    movable = (sm.kind == FREE).ravel()
    face = sm.points.face.copy()
    bary = sm.points.bary.copy()
    alpha = np.ones(nu * nv)
    prev = np.zeros((nu * nv, 3))
    want = ref.relax_sweeps(
        mesh, face, bary, nu, nv, movable, tangent, guard, alpha, prev, 5, 0, 3, 0.5, 1.0, 0.0,
        lazy, fold,
    )  # fmt: skip
    done, worst, rms = K.relax_sweeps(
        mesh.vertices, mesh.faces, mesh.face_neighbors, face, bary, nu, nv, movable, tangent,
        guard, alpha, prev,
        5, 0, 3, 0.5, 1.0, 0.0, tol.BARY_EPS, 10_000, lazy, fold,
    )  # fmt: skip
    got = mesh.xyz(SurfacePoints(face, bary))
    assert done == want[2] == 5
    assert_allclose(got, mesh.xyz(SurfacePoints(want[0], want[1])), atol=1e-9 * mesh.bbox_diagonal)
    assert_allclose([worst, rms], want[3:], rtol=1e-6)
    assert_allclose(bary.sum(axis=1), 1.0, atol=1e-12)


def test_spring_force_matches_oracle(rng):
    X = rng.normal(size=(12, 3))
    nv = 4
    nrm = np.array([0.6, 0.0, 0.8])
    N = np.tile(nrm, (12, 1))
    for p in (5, 6):
        for tangent in (False, True):
            *out, h = K.spring_force(X, N, nv, p, 0.7, 0.3, *nrm, tangent, False)
            want, wh = ref.spring_force(X, nv, p, 0.7, 0.3, nrm if tangent else None)
            assert_allclose(out, want, atol=1e-14)
            assert_allclose(h, wh)


def test_spring_force_follows_the_line_across_a_fold(rng):
    """A neighbour whose normal faces away (a curled rim crossed) pulls along the grid line,
    away from the neighbour on the other side, with its own spring length."""
    X = rng.normal(size=(12, 3))
    nv = 4
    nrm = np.array([0.6, 0.0, 0.8])
    for p, across in ((5, 5 + nv), (5, 4), (6, 6 - nv), (6, 7)):
        N = np.tile(nrm, (12, 1))
        N[across] = -nrm
        *out, h = K.spring_force(X, N, nv, p, 0.7, 0.3, *nrm, True, True)
        want, wh = ref.spring_force(X, nv, p, 0.7, 0.3, nrm, N)
        assert_allclose(out, want, atol=1e-14)
        assert_allclose(h, wh)
        *plain, _ = K.spring_force(X, N, nv, p, 0.7, 0.3, *nrm, True, False)
        assert not np.allclose(out, plain)  # the fold changed the force
        # with only the fairness force: the vector across the fold is the opposite
        # neighbour's, reversed and rescaled, so the two along the line cancel in direction
        *fair, _ = K.spring_force(X, N, nv, p, 0.0, 1.0, *nrm, True, True)
        other = 2 * p - across

        def t(q, p=p):
            d = X[q] - X[p]
            return d - (d @ nrm) * nrm

        lq = np.linalg.norm(X[across] - X[p])
        lo = np.linalg.norm(X[other] - X[p])
        to_other = t(other) * (lo / np.linalg.norm(t(other)))
        side = [q for q in (p - nv, p + nv, p - 1, p + 1) if q not in (across, other)]
        rest = sum(t(q) * (np.linalg.norm(X[q] - X[p]) / np.linalg.norm(t(q))) for q in side)
        expect = 0.25 * (rest + to_other - to_other * (lq / lo))
        assert_allclose(fair, expect, atol=1e-12)


@pytest.mark.parametrize("name", ["cap", "spot"])
def test_find_midpoints_matches_oracle(patches, name, rng):
    from meshfit.surface import random_surface_points

    mesh = patches[name].mesh
    a = random_surface_points(mesh, 40, rng=rng)
    b = SurfacePoints(a.face[::-1].copy(), a.bary[::-1].copy())
    vfp, vf = mesh.vertex_faces
    indptr, indices = mesh.vertex_adjacency
    on_boundary = np.zeros(mesh.n_vertices, dtype=bool)
    for loop in mesh.boundary_loops:
        on_boundary[loop] = True
    f, bb = K.find_midpoints(
        mesh.vertices, mesh.faces, mesh.face_neighbors, vfp, vf, indptr, indices, on_boundary,
        a.face, a.bary, b.face, b.bary, 3, 2000, tol.BARY_EPS, 10_000,
    )  # fmt: skip
    wf, wb = ref.find_midpoints(mesh, a, b, 3, 2000, on_boundary)
    assert_allclose(
        mesh.xyz(SurfacePoints(f, bb)),
        mesh.xyz(SurfacePoints(wf, wb)),
        atol=1e-9 * mesh.bbox_diagonal,
    )


def test_grid_xyz_is_mesh_xyz(patches, rng):
    from meshfit.surface import random_surface_points

    mesh = patches["spot"].mesh
    sp = random_surface_points(mesh, 50, rng=rng)
    assert_allclose(K.grid_xyz(mesh.vertices, mesh.faces, sp.face, sp.bary), mesh.xyz(sp))


def test_folded_cells_kernel_matches_the_metric(patches, rng):
    from meshfit.springs import grid_metrics

    patch = patches["spot"]
    mesh = patch.mesh
    sm = resample_patch(patch, SpringOptions(level=2, metrics=False)).final
    face = sm.points.face.copy()
    bary = sm.points.bary.copy()
    # scramble some interior points to make folds
    nu, nv = sm.shape
    idx = np.arange(nu * nv).reshape(nu, nv)[2:-2, 2:-2].ravel()
    pick = rng.choice(idx, size=6, replace=False)
    face[pick] = face[pick[::-1]]
    bary[pick] = bary[pick[::-1]]
    got = K.folded_cells(mesh.vertices, mesh.faces, face, bary, nu, nv)
    X = mesh.xyz(SurfacePoints(face, bary)).reshape(nu, nv, 3)
    N = mesh.face_normals[face].reshape(nu, nv, 3)
    want = grid_metrics(mesh, X, N, fidelity=False)["folded"]
    assert got.sum() == want > 0


def test_window_trials_matches_oracle(patches, rng):
    # a side window of a relaxed grid, two lines deep, with its side points moved to random
    # places: every trial's fold count and shortest chord as the oracle finds them
    patch = patches["spot"]
    mesh = patch.mesh
    sm = resample_patch(patch, SpringOptions(level=2, metrics=False)).final
    nu, nv = sm.shape
    win = np.arange(nu * nv).reshape(nu, nv)[2:9, :2].ravel()
    face, bary = sm.points.face[win].copy(), sm.points.bary[win].copy()
    at = np.array([2, 4, 6, 8, 10])
    pool = sm.points.face.size
    picks = rng.integers(0, pool, size=(12, at.size))
    t_face = sm.points.face[picks]
    t_bary = sm.points.bary[picks]
    got = K.window_trials(mesh.vertices, mesh.faces, face, bary, 7, 2, at, t_face, t_bary)
    want = ref.window_trials(mesh, face, bary, 7, 2, at, t_face, t_bary)
    assert_array_equal(got[0], want[0])
    assert got[0][1:].max() > 0  # some trials fold the window
    assert_allclose(got[1], want[1], rtol=1e-12)


def test_locate_uv_matches_oracle(patches, rng):
    from meshfit.springs.planar import square_map
    from meshfit.springs.resample import _sides

    patch = patches["spot"]
    pmap = square_map(patch.mesh, _sides(patch))
    q = np.concatenate([rng.uniform(0.0, 1.0, (60, 2)), [[0, 0], [1, 1], [0.5, 0], [1, 0.3]]])
    face, bary = K.locate_uv(pmap.uv, patch.mesh.faces, *pmap._buckets, pmap._g, q)
    f_ref, b_ref = ref.locate_uv(pmap.uv, patch.mesh.faces, q)
    # a point on an edge may go to either face: compare the located parameters
    F = patch.mesh.faces
    got = np.einsum("ij,ijk->ik", bary, pmap.uv[F[face]])
    want = np.einsum("ij,ijk->ik", b_ref, pmap.uv[F[f_ref]])
    assert_allclose(got, want, atol=1e-12)
    assert_allclose(got, q, atol=1e-12)
    assert (bary >= 0).all() and (face >= 0).all()


def _folded_grid(patch, rng, k=4, shift=2):
    """A level-1 spring mesh of the patch with ``k`` interior points moved ``shift`` cells
    over (folded cells around them)."""
    sm = resample_patch(patch, SpringOptions(level=1, metrics=False)).final
    nu, nv = sm.shape
    face = sm.points.face.copy()
    bary = sm.points.bary.copy()
    idx = np.arange(nu * nv).reshape(nu, nv)
    pick = rng.choice(idx[3:-3, 3:-3].ravel(), size=k, replace=False)
    face[pick], bary[pick] = face[pick + shift * nv], bary[pick + shift * nv]
    return sm, face, bary


@pytest.mark.parametrize("name", ["cap", "spot"])
def test_repair_folds_matches_oracle(patches, name, rng):
    mesh = patches[name].mesh
    sm, face, bary = _folded_grid(patches[name], rng)
    nu, nv = sm.shape
    movable = (sm.kind == FREE).ravel()
    before = K.folded_cells(mesh.vertices, mesh.faces, face, bary, nu, nv).sum()
    want_f, want_b = ref.repair_folds(mesh, face, bary, nu, nv, movable, 2, 8, 0.3)
    K.repair_folds(
        mesh.vertices, mesh.faces, mesh.face_neighbors, face, bary, nu, nv, movable,
        2, 8, 0.3, tol.BARY_EPS, 10_000,
    )  # fmt: skip
    assert before > 0
    assert_allclose(
        mesh.xyz(SurfacePoints(face, bary)),
        mesh.xyz(SurfacePoints(want_f, want_b)),
        atol=1e-9 * mesh.bbox_diagonal,
    )
    assert_allclose(bary.sum(axis=1), 1.0, atol=1e-12)
    assert (bary >= -tol.BARY_EPS).all()


@pytest.mark.parametrize("name", ["cap", "spot"])
def test_repair_folds_unfolds_moved_points(patches, name, rng):
    from meshfit.springs.relax import repair_folds
    from meshfit.springs.resample import _sides
    from meshfit.springs.state import State

    patch = patches[name]
    mesh = patch.mesh
    sm, face, bary = _folded_grid(patch, rng, shift=1)
    nu, nv = sm.shape
    state = State(mesh, 0, _sides(patch), [], [], {}, [nu - 1], [nv - 1])
    state.face, state.bary = face, bary
    keep = ~(sm.kind == FREE).ravel()
    fixed_xyz = mesh.xyz(SurfacePoints(face[keep], bary[keep]))
    assert K.folded_cells(mesh.vertices, mesh.faces, face, bary, nu, nv).sum() > 0
    assert repair_folds(state) == 0
    assert not K.folded_cells(mesh.vertices, mesh.faces, state.face, state.bary, nu, nv).any()
    # only free points move
    assert_allclose(mesh.xyz(SurfacePoints(state.face[keep], state.bary[keep])), fixed_xyz)


@pytest.mark.parametrize("rounds", [1, 30, 200])
def test_chord_positions_match_oracle(rng, rounds):
    from meshfit.springs.state import chord_positions

    for trial in range(20):
        k = int(rng.integers(3, 60))
        # a bent polyline with a repeated point and uneven edges
        xyz = np.cumsum(rng.normal(size=(k, 3)) * rng.uniform(0.1, 2.0, (k, 1)), axis=0)
        if trial % 4 == 0:
            xyz[k // 2] = xyz[k // 2 - 1]
        arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(xyz, axis=0), axis=1))])
        sections = int(rng.integers(1, 4))
        inner = np.sort(rng.uniform(0.0, arc[-1], sections - 1)).tolist()
        breaks = [0.0, *inner, float(arc[-1])]
        counts = [int(c) for c in rng.integers(1, 12, sections)]
        got = chord_positions(xyz, arc, breaks, counts, rounds=rounds)
        want = ref.chord_positions(xyz, arc, breaks, counts, rounds)
        # the rounds agree to rounding (einsum and the loop may order sums differently)
        assert_allclose(got, want, rtol=0, atol=1e-9 * arc[-1])
        assert (np.diff(got) >= 0).all()


def _plane_state():
    """The building state of a flat 2 x 1 patch's level-1 spring mesh (33 x 17 points)."""
    from .patches import plane_map, spring_state

    patch = param_patch(plane_map(), 24, 24, jitter=0.0)
    return spring_state(patch, resample_patch(patch, SpringOptions(level=1, metrics=False)).final)


def test_side_points_slide_back_between_their_neighbours():
    # a side point pushed past its neighbour folds the two boundary cells beside it whatever
    # the free points do; sliding it along the side (between its static neighbours) unfolds
    # them; the side points within SLIDE_TAPER places go along by tapering amounts, in order
    # and on the side, and nothing else moves
    from meshfit.springs.relax import SLIDE_TAPER, repair_folds, slide_side_points

    state = _plane_state()
    mesh, nu, nv = state.mesh, state.nu, state.nv
    g, g2 = 4 * nv, 6 * nv  # bottom side points 4 and 6
    before = mesh.xyz(SurfacePoints(state.face, state.bary))
    state.face[g], state.bary[g] = state.face[g2], state.bary[g2]
    assert K.folded_cells(mesh.vertices, mesh.faces, state.face, state.bary, nu, nv).any()
    assert repair_folds(state) > 0  # moving free points cannot help
    moved = mesh.xyz(SurfacePoints(state.face, state.bary))
    assert slide_side_points(state) == 0
    after = mesh.xyz(SurfacePoints(state.face, state.bary))
    changed = np.flatnonzero(np.linalg.norm(after - moved, axis=1) > 0)
    assert g in changed
    side = [k * nv for k in range(max(1, 4 - SLIDE_TAPER), min(nu - 1, 5 + SLIDE_TAPER))]
    assert set(changed.tolist()) <= set(side)
    # back between its neighbours, every bottom side point on the side and in order
    x = after[g, 0]
    assert before[3 * nv, 0] < x < before[5 * nv, 0]
    assert np.abs(after[::nv][:, 1]).max() <= 1e-12
    assert (np.diff(after[::nv][:, 0]) > 0).all()


def test_pinched_side_points_slide_apart():
    # a side point nearly on top of its neighbour (a side stepping back over about one grid
    # spacing) folds nothing, but leaves a near-zero interval on the boundary iso-curve:
    # unpinch_side_points slides it apart along the side, folding nothing
    from meshfit.springs.relax import PINCH_RATIO, unpinch_side_points
    from meshfit.types import SurfacePoints as SP

    state = _plane_state()
    mesh, nu, nv = state.mesh, state.nu, state.nv
    bottom = np.arange(nu) * nv
    X = mesh.xyz(SP(state.face, state.bary))
    # bottom side point 4 moved 95% of the way to point 5, on the side
    p = mesh.closest_points((0.05 * X[bottom[4]] + 0.95 * X[bottom[5]])[None]).points
    state.face[bottom[4]], state.bary[bottom[4]] = p.face[0], p.bary[0]
    K_fold = K.folded_cells(mesh.vertices, mesh.faces, state.face, state.bary, nu, nv)
    assert not K_fold.any()

    def chords():
        Y = mesh.xyz(SP(state.face[bottom], state.bary[bottom]))
        return np.linalg.norm(np.diff(Y, axis=0), axis=1), Y

    d0, _ = chords()
    assert d0.min() < PINCH_RATIO * np.median(d0)
    assert unpinch_side_points(state) >= 1
    d1, Y = chords()
    assert d1.min() >= PINCH_RATIO * np.median(d1)  # 0.05 -> 0.97 of the median here
    assert not K.folded_cells(mesh.vertices, mesh.faces, state.face, state.bary, nu, nv).any()
    assert np.abs(Y[:, 1]).max() <= 1e-12 and (np.diff(Y[:, 0]) > 0).all()
    # no pinch left: nothing moves
    before = state.face.copy(), state.bary.copy()
    assert unpinch_side_points(state) == 0
    assert (state.face == before[0]).all() and (state.bary == before[1]).all()


def test_chain_points_matches_oracle(rng):
    k = 12
    arc = np.concatenate([[0.0], np.cumsum(rng.uniform(0.0, 1.0, k - 1))])
    arc[5] = arc[4]  # a zero-length edge
    ef = rng.integers(0, 50, k - 1)
    ea = rng.integers(0, 3, k - 1)
    eb = (ea + rng.integers(1, 3, k - 1)) % 3
    positions = np.concatenate(
        [rng.uniform(-0.5, arc[-1] + 0.5, 200), arc, [arc[-1], 0.0, -1.0, arc[-1] + 1.0]]
    )
    face, bary = K.chain_points(arc, ef, ea, eb, positions)
    want_face, want_bary = ref.chain_points(arc, ef, ea, eb, positions)
    assert_array_equal(face, want_face)
    assert_array_equal(bary, want_bary)
    assert_allclose(bary.sum(axis=1), 1.0, rtol=0, atol=1e-15)


@pytest.mark.parametrize(("u_lines", "v_lines"), [((), ()), ((3,), (2, 5)), ((1, 4), ())])
def test_grid_spacing_matches_oracle(rng, u_lines, v_lines):
    from meshfit.springs.metrics import spacing

    X = rng.normal(size=(7, 9, 3))
    X[3, 3:5] = X[2, 3:5]  # a cell side of zero length: an infinite aspect ratio
    X[:, 8] = X[0, 8]  # a column of points in one place: zero mean spacing, variation 0
    cv, aspect = spacing(X, u_lines, v_lines)
    want_cv, want_aspect = ref.spacing(X, u_lines, v_lines)
    assert cv.shape == want_cv.shape and aspect.shape == want_aspect.shape
    assert_allclose(cv, want_cv, rtol=1e-12, atol=1e-15)
    assert_allclose(aspect, want_aspect, rtol=1e-12)
    assert np.isinf(aspect).any()
    assert cv[8] == 0.0  # the first u piece's column 8


@pytest.mark.parametrize("ratio", [0.0, 0.4, 0.9, 2.0])
def test_pinched_side_points_match_oracle(patches, rng, ratio):
    from meshfit.surface import random_surface_points

    mesh = patches["spot"].mesh
    nu, nv = 6, 9
    pts = random_surface_points(mesh, nu * nv, rng)
    args = (mesh.vertices, mesh.faces, np.ascontiguousarray(pts.face), np.array(pts.bary))
    got = K.pinched_side_points(*args, nu, nv, ratio)
    want = ref.pinched_side_points(*args, nu, nv, ratio)
    assert_array_equal(got, want)
    if ratio >= 2.0:  # the shortest chord of a side is below twice its median
        assert len(got) > 0


def test_red_black_mean_matches_oracle(rng):
    uv = rng.uniform(size=(9, 11, 2))
    win = np.zeros((9, 11), dtype=bool)
    win[2:6, 3:9] = True
    win[7, 1] = True
    ii, jj = np.nonzero(win)
    want = ref.red_black_mean(uv, ii, jj, 7)
    got = uv.copy()
    K.red_black_mean(got, ii.astype(np.int64), jj.astype(np.int64), 7)
    assert_array_equal(got, want)
    assert not np.array_equal(got, uv)


@pytest.mark.parametrize(("u_lines", "v_lines"), [((), ()), ((2,), (3, 5))])
def test_line_spacing_matches_oracle(patches, rng, u_lines, v_lines):
    from meshfit.surface import random_surface_points

    mesh = patches["spot"].mesh
    nu, nv = 5, 8
    pts = random_surface_points(mesh, nu * nv, rng)
    args = (mesh.vertices, mesh.faces, np.ascontiguousarray(pts.face), np.array(pts.bary), nu, nv)
    ends_u = np.array([0, *u_lines, nu - 1], dtype=np.int64)
    ends_v = np.array([0, *v_lines, nv - 1], dtype=np.int64)
    col, row, med = K.line_spacing(*args, ends_u, ends_v)
    want_col, want_row, want_med = ref.line_spacing(*args, u_lines, v_lines)
    assert_allclose(col, want_col, rtol=1e-12)
    assert_allclose(row, want_row, rtol=1e-12)
    assert med == pytest.approx(want_med, rel=1e-12)


def test_maxmin_point_matches_linear_programming(rng):
    # the exact vertex enumeration against HiGHS, including bounded-by-the-box optima (one
    # function), parallel functions and duplicates
    for trial in range(400):
        m = int(rng.integers(1, 9))
        A = rng.normal(size=(8, 3))
        if trial % 5 == 0 and m > 1:
            A[1, :2] = A[0, :2]  # parallel
        if trial % 7 == 0 and m > 2:
            A[2] = A[0]  # duplicate
        px, py = rng.normal(size=2)
        h = float(rng.uniform(0.05, 3.0))
        x, y, s = K.maxmin_point(A, m, px, py, h)
        want = ref.maxmin_point(A, m, px, py, h)
        assert s == pytest.approx(want, rel=1e-9, abs=1e-9)
        assert abs(x - px) <= h * (1 + 1e-12) and abs(y - py) <= h * (1 + 1e-12)
        assert s == pytest.approx(min(A[:m, 0] * x + A[:m, 1] * y + A[:m, 2]), abs=1e-12)


def test_chart_untangle_unfolds_a_scrambled_plane_grid(rng):
    # a 9 x 9 unit grid whose inner points are scrambled by up to 0.9 spacings: the rounds
    # never lower the least triangle area and end with every cell unfolded; the border
    # points stay
    nu = nv = 9
    g = np.stack(np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij"), axis=-1)
    for _ in range(5):
        Y = g.reshape(-1, 2).astype(float)
        var = np.zeros((nu, nv), dtype=bool)
        var[1:-1, 1:-1] = True
        var = var.ravel()
        Y[var] += rng.uniform(-0.9, 0.9, size=(var.sum(), 2))
        border = Y[~var].copy()
        before = ref.chart_least_area(Y, nu, nv, var)
        assert before < 0
        last = before
        for _ in range(30):
            done, worst = K.chart_untangle(Y, nu, nv, var, 1.0, 1, 0.1)
            assert done == (1 if last < 0.1 else 0)
            assert worst == pytest.approx(ref.chart_least_area(Y, nu, nv, var), abs=1e-12)
            assert worst >= last - 1e-12
            last = worst
        assert last >= 0.1
        assert_array_equal(Y[~var], border)


def test_untangle_in_charts_unfolds_a_tangle_in_place():
    # four free points of a flat grid moved onto each other's places (a tangle that no single
    # move undoes): untangled, with only free points moved and every point on the patch
    from meshfit.springs.relax import untangle_in_charts

    state = _plane_state()
    mesh, nu, nv = state.mesh, state.nu, state.nv
    keep = ~(state.kind() == FREE).ravel()
    fixed_xyz = mesh.xyz(SurfacePoints(state.face[keep], state.bary[keep]))
    i, j = 12, 8
    cyc = [i * nv + j, (i + 1) * nv + j + 1, (i + 1) * nv + j, i * nv + j + 1]
    state.face[cyc], state.bary[cyc] = state.face[cyc[::-1]], state.bary[cyc[::-1]]
    assert K.folded_cells(mesh.vertices, mesh.faces, state.face, state.bary, nu, nv).sum() > 0
    assert untangle_in_charts(state) == 0
    assert not K.folded_cells(mesh.vertices, mesh.faces, state.face, state.bary, nu, nv).any()
    assert_allclose(mesh.xyz(SurfacePoints(state.face[keep], state.bary[keep])), fixed_xyz)
    assert (state.bary >= -tol.BARY_EPS).all()
    assert_allclose(state.bary.sum(axis=1), 1.0, atol=1e-12)


def test_untangle_in_charts_keeps_the_grid_when_it_cannot_help():
    # a side point pushed past its neighbour: no free point can unfold its cells, so the
    # grid is left exactly as it was
    from meshfit.springs.relax import untangle_in_charts

    state = _plane_state()
    mesh, nu, nv = state.mesh, state.nu, state.nv
    g, g2 = 4 * nv, 6 * nv
    state.face[g], state.bary[g] = state.face[g2], state.bary[g2]
    before = K.folded_cells(mesh.vertices, mesh.faces, state.face, state.bary, nu, nv).sum()
    face, bary = state.face.copy(), state.bary.copy()
    assert untangle_in_charts(state) == before > 0
    assert_array_equal(state.face, face)
    assert_array_equal(state.bary, bary)
