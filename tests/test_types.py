"""SurfacePoints, SurfaceCurve and the argument checks in meshfit._validate."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from numpy.testing import assert_array_equal

from meshfit import errors
from meshfit._validate import as_points, as_surface_points, as_vectors, as_vertex_index
from meshfit.types import SurfaceCurve, SurfacePoints

from .conftest import analytic_mesh


def points(n: int = 5) -> SurfacePoints:
    face = np.arange(n, dtype=np.int64) * 3
    bary = np.tile([0.2, 0.3, 0.5], (n, 1)) + np.arange(n)[:, None] * [0.1, -0.1, 0.0]
    return SurfacePoints(face, bary)


# ------------------------------------------------------------------------ SurfacePoints
@pytest.mark.parametrize(
    ("face", "bary", "match"),
    [
        (np.zeros((2, 1), np.int64), np.zeros((2, 3)), "face must be a 1-d integer array"),
        (np.array([0.0, 1.0]), np.zeros((2, 3)), "face must be a 1-d integer array"),
        (np.array([True, False]), np.zeros((2, 3)), "face must be a 1-d integer array"),
        (np.array([0, 1]), np.zeros((2, 2)), r"bary must have shape \(2, 3\), got \(2, 2\)"),
        (np.array([0, 1]), np.zeros((3, 3)), r"bary must have shape \(2, 3\), got \(3, 3\)"),
        (np.array([0, 1]), np.zeros(6), r"bary must have shape \(2, 3\), got \(6,\)"),
        (np.array([0, 1]), [[1, 0, 0], [np.nan, 0.5, 0.5]], "not finite at point 1"),
        (np.array([0, 1, 2]), [[1, 0, 0], [1, 0, 0], [np.inf, 0, 0]], "not finite at point 2"),
    ],
)
def test_surface_points_validation(face, bary, match):
    with pytest.raises(errors.InputError, match=match):
        SurfacePoints(face, bary)


def test_surface_points_dtypes_and_copies():
    face = np.array([1, 2], dtype=np.int32)
    bary = np.array([[1, 0, 0], [0, 1, 0]], dtype=np.float32)
    sp = SurfacePoints(face, bary)
    assert sp.face.dtype == np.int64
    assert sp.bary.dtype == np.float64
    assert sp.face.flags.c_contiguous and sp.bary.flags.c_contiguous
    face64 = np.array([1, 2])
    bary64 = np.array([[1.0, 0, 0], [0, 1, 0]])
    sp = SurfacePoints(face64, bary64)
    face64[0] = 7
    bary64[0, 0] = 7.0
    assert sp.face[0] == 1  # the caller's arrays were copied
    assert sp.bary[0, 0] == 1.0
    empty = SurfacePoints([], np.zeros((0, 3)))  # an empty list has dtype float: allowed
    assert len(empty) == 0
    assert empty.face.dtype == np.int64


def test_surface_points_read_only():
    sp = points()
    with pytest.raises(ValueError, match="read-only"):
        sp.face[0] = 1
    with pytest.raises(ValueError, match="read-only"):
        sp.bary[0, 0] = 1.0
    with pytest.raises(ValueError):
        sp.bary.flags.writeable = True
    with pytest.raises(dataclasses.FrozenInstanceError):
        sp.face = np.zeros(5, np.int64)


def test_surface_points_indexing():
    sp = points(5)
    assert len(sp) == 5
    one = sp[2]
    assert isinstance(one, SurfacePoints)
    assert len(one) == 1
    assert_array_equal(one.face, [6])
    assert_array_equal(one.bary, sp.bary[2:3])
    assert_array_equal(sp[-1].face, [12])
    assert_array_equal(sp[-2].face, [9])
    assert_array_equal(sp[np.int64(1)].face, [3])
    assert_array_equal(sp[1:4].face, [3, 6, 9])
    assert_array_equal(sp[::-2].face, [12, 6, 0])
    assert_array_equal(sp[np.array([4, 0, 4])].face, [12, 0, 12])
    assert_array_equal(sp[sp.face > 5].bary, sp.bary[2:])
    assert len(sp[5:]) == 0
    # an integer out of range raises, as for arrays (it returned an empty set before)
    for bad in (5, 7, -6):
        with pytest.raises(IndexError, match=f"index {bad} is out of range for 5"):
            sp[bad]


def test_surface_points_concatenate():
    a, b = points(3), points(2)[::-1]
    c = SurfacePoints.concatenate([a, b])
    assert_array_equal(c.face, [0, 3, 6, 3, 0])
    assert_array_equal(c.bary, np.vstack([a.bary, b.bary]))
    assert not c.face.flags.writeable
    empty = SurfacePoints.concatenate([])
    assert len(empty) == 0
    assert empty.bary.shape == (0, 3)
    assert_array_equal(SurfacePoints.concatenate([a]).face, a.face)


def test_surface_points_at_vertices():
    faces = np.array([[0, 1, 2], [2, 1, 3]])
    sp = SurfacePoints.at_vertices(faces, [3, 0, 2])
    assert_array_equal(sp.face, [1, 0, 0])  # the first face using each vertex
    assert_array_equal(sp.bary, [[0, 0, 1], [1, 0, 0], [0, 0, 1]])


# ------------------------------------------------------------------------ SurfaceCurve
def test_surface_curve_kind():
    sp = points(4)
    curve = SurfaceCurve(sp)
    assert curve.kind == "boundary"
    assert curve.closed is False
    assert len(curve) == 4
    assert SurfaceCurve(sp, closed=True, kind="feature").kind == "feature"
    with pytest.raises(errors.InputError, match="'boundary' or 'feature', got 'crease'"):
        SurfaceCurve(sp, kind="crease")
    with pytest.raises(dataclasses.FrozenInstanceError):
        curve.closed = True


# --------------------------------------------------------------------------- _validate
def test_as_points():
    a = as_points([1, 2, 3])
    assert a.shape == (1, 3)
    assert a.dtype == np.float64
    b = as_points(np.arange(12, dtype=np.int32).reshape(4, 3)[::-1])
    assert b.flags.c_contiguous
    assert_array_equal(b[0], [9, 10, 11])
    assert as_points(np.zeros((0, 3))).shape == (0, 3)
    with pytest.raises(errors.InputError, match=r"xyz must have shape \(n, 3\), got \(2, 2\)"):
        as_points(np.zeros((2, 2)))
    with pytest.raises(errors.InputError, match=r"q must have shape \(n, 3\), got \(4,\)"):
        as_points(np.zeros(4), name="q")
    with pytest.raises(errors.InputError, match="must be numeric"):
        as_points([["a", "b", "c"]])
    with pytest.raises(errors.InputError, match="NaN or infinite value in row 2"):
        as_points([[0, 0, 0], [1, 1, 1], [0, np.inf, 0]])


def test_as_vectors():
    v = as_vectors([0, 0, 1], n=4, name="step")
    assert v.shape == (4, 3)
    assert_array_equal(v[:, 2], 1.0)
    assert as_vectors(np.ones((1, 3)), n=1, name="s").shape == (1, 3)
    with pytest.raises(errors.InputError, match="step must have 4 rows, got 2"):
        as_vectors(np.ones((2, 3)), n=4, name="step")
    with pytest.raises(errors.InputError, match="step has a NaN"):
        as_vectors([np.nan, 0, 0], n=4, name="step")


def test_as_surface_points():
    mesh = analytic_mesh("plane")
    ok = SurfacePoints([0, mesh.n_faces - 1], [[1, 0, 0], [0.2, 0.3, 0.5]])
    assert as_surface_points(mesh, ok) is ok
    with pytest.raises(errors.InputError, match="must be SurfacePoints, got tuple"):
        as_surface_points(mesh, ([0], [[1, 0, 0]]))
    bad = SurfacePoints([0, mesh.n_faces], [[1, 0, 0], [1, 0, 0]])
    with pytest.raises(errors.InputError, match=rf"pts\[1\] is on face {mesh.n_faces}, outside"):
        as_surface_points(mesh, bad, name="pts")
    with pytest.raises(errors.InputError, match=r"points\[0\] is on face -1"):
        as_surface_points(mesh, SurfacePoints([-1], [[1, 0, 0]]))
    with pytest.raises(
        errors.InputError,
        match=r"points\[1\] has barycentric coordinates "
        r"summing to 0\.8999",
    ):
        as_surface_points(mesh, SurfacePoints([0, 1], [[1, 0, 0], [0.3, 0.3, 0.3]]))
    with pytest.raises(errors.InputError, match=r"points\[0\] has a negative barycentric"):
        as_surface_points(mesh, SurfacePoints([0], [[1.5, -0.5, 0]]))
    empty = SurfacePoints([], np.zeros((0, 3)))
    assert as_surface_points(mesh, empty) is empty


def test_as_vertex_index():
    mesh = analytic_mesh("plane")
    assert as_vertex_index(mesh, 3) == 3
    assert as_vertex_index(mesh, np.int32(4)) == 4
    assert as_vertex_index(mesh, 5.0) == 5
    assert type(as_vertex_index(mesh, np.int64(2))) is int
    for bad in (-1, mesh.n_vertices, 2.5):
        with pytest.raises(errors.InputError, match="is not a vertex index"):
            as_vertex_index(mesh, bad)
    with pytest.raises(errors.InputError, match="start must be a vertex index, got 'a'"):
        as_vertex_index(mesh, "a", name="start")
    with pytest.raises(errors.InputError, match="must be a vertex index"):
        as_vertex_index(mesh, None)


def test_errors_hierarchy():
    assert issubclass(errors.InputError, ValueError)
    for cls in (
        errors.InputError,
        errors.MeshFileError,
        errors.MeshValidationError,
        errors.PathError,
        errors.CutError,
    ):
        assert issubclass(cls, errors.MeshfitError)
    kinds = set()
    for name in errors.__all__:
        cls = getattr(errors, name)
        if issubclass(cls, errors.MeshValidationError) and cls is not errors.MeshValidationError:
            kinds.add(cls.kind)
    assert len(kinds) == 9  # one distinct kind per validation error
    e = errors.NonManifoldEdgeError("x", first=(1, 2), count=3)
    assert (e.first, e.count, str(e)) == ((1, 2), 3, "x")


def test_surface_points_owned_arrays_become_read_only():
    face = np.array([0, 2], dtype=np.int64)
    bary = np.array([[1.0, 0.0, 0.0], [0.2, 0.3, 0.5]])
    pts = SurfacePoints.owned(face, bary)
    assert len(pts) == 2 and np.array_equal(pts.face, [0, 2])
    assert np.shares_memory(pts.bary, bary)  # handed over, not copied
    for a in (pts.face, pts.bary, face, bary):
        assert not a.flags.writeable
    with pytest.raises(ValueError):
        pts.face.flags.writeable = True
    bad = np.array([[1.0, 0.0, 0.0], [np.nan, 0.5, 0.5]])
    with pytest.raises(errors.InputError, match="not finite at point 1"):
        SurfacePoints.owned(np.array([0, 1], dtype=np.int64), bad)


def test_subsets_and_joins_stay_read_only_and_do_not_alias_writeable_memory():
    sp = SurfacePoints(np.arange(6), np.tile([0.2, 0.3, 0.5], (6, 1)))
    for sub in (sp[np.array([4, 1])], sp[sp.face > 2], sp[1:4], sp[::-2], sp[2]):
        for a in (sub.face, sub.bary):
            assert not a.flags.writeable
            with pytest.raises(ValueError):
                a.flags.writeable = True
    joined = SurfacePoints.concatenate([sp[1:3], sp[np.array([5])]])
    assert_array_equal(joined.face, [1, 2, 5])
    assert joined.face.dtype == np.int64 and not joined.bary.flags.writeable
    with pytest.raises(ValueError):
        joined.bary.flags.writeable = True
