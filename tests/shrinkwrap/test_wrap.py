import dataclasses
import itertools

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from meshfit import errors, tol
from meshfit.mesh import Mesh
from meshfit.shrinkwrap import (
    BaseOptions,
    WrapOptions,
    base_mesh,
    fill_holes,
    icosahedron,
    level_metrics,
    octahedron,
    shrink_wrap,
    spherical_orientation,
    wrap_report,
)

from ..conftest import analytic_mesh, real_mesh
from ..shapes import icosphere, quadruped
from .conftest import smap, wrap

#: the issue's targets
MAX_BASE_FACES = 100
MAX_CELL_RATIO = 3.0
MAX_RMS_L5 = 0.0005  # 0.05 % of the bbox diagonal
MIN_ANGLE_DEG = 5.0
#: level-5 triangles facing against the input, as a fraction of the faces
MAX_NORMAL_FLIPS = 1e-3


def test_icosahedron_is_outward_and_unit():
    v, f = icosahedron()
    assert f.shape == (20, 3)
    assert (spherical_orientation(v, f) > 0).all()
    assert_allclose(np.linalg.norm(v, axis=1), 1.0)


@pytest.mark.parametrize("name", ["igea", "nefertiti"])
def test_base_mesh_is_small_and_balanced(name):
    b = wrap(name, 5).base
    assert len(b.faces) <= MAX_BASE_FACES
    assert b.area_ratio <= MAX_CELL_RATIO
    assert (spherical_orientation(b.sphere, b.faces) > 0).all()
    assert_allclose(b.cell_area.sum(), real_mesh(name).area, rtol=1e-9)


def test_octahedron_is_outward_and_unit():
    v, f = octahedron()
    assert v.shape == (6, 3) and f.shape == (8, 3)
    assert_allclose(np.linalg.norm(v, axis=1), 1.0)
    assert (spherical_orientation(v, f) > 0).all()


def test_base_mesh_from_the_octahedron():
    # 8 triangles, or more by edge splits: coarser bases than the icosahedron's 20
    sm = smap("spot")
    for faces in (8, 12):
        b = base_mesh(sm, BaseOptions(start="octahedron", max_faces=faces, min_faces=faces))
        assert len(b.faces) == faces
        assert (spherical_orientation(b.sphere, b.faces) > 0).all()
        assert_allclose(b.cell_area.sum(), real_mesh("spot").area, rtol=1e-9)
    # the options are checked when they are made, before any work
    with pytest.raises(errors.InputError, match="at least 8 \\(an octahedron\\)"):
        BaseOptions(start="octahedron", max_faces=6)
    with pytest.raises(errors.InputError, match="at least 20 \\(an icosahedron\\)"):
        BaseOptions(max_faces=12)
    with pytest.raises(errors.InputError, match="start must be one of"):
        BaseOptions(start="cube")
    with pytest.raises(errors.InputError, match="alpha must be in"):
        BaseOptions(alpha=0.0)
    with pytest.raises(errors.InputError, match="relaxation must be"):
        BaseOptions(relaxation="laplace")


def test_umbrella_base_relaxation_runs_without_flips():
    b = base_mesh(smap("spot"), BaseOptions(relaxation="umbrella", iterations=5, max_faces=30))
    assert (spherical_orientation(b.sphere, b.faces) > 0).all()


_SPOT_RMS = pytest.mark.xfail(
    strict=True,
    reason="spot level-5 RMS 0.105% > 0.05% (measured, default options; input-to-wrap 0.105%, "
    "wrap-to-input 0.027%): the ear and horn tips are sampled about 3x coarser than the mean "
    "and cut (Hausdorff 0.85%). Tried: 10 / 20 surface iterations 0.090 / 0.081% (min angle "
    "5.7 / 3.4 deg), area densities at every level 0.081%, projected 3D edge midpoints in the "
    "surface phase 0.088% (nefertiti 0.048 -> 0.051%), curvature-weighted densities with an "
    "earlier switch 0.058-0.060% (min angle 1.3-3.1 deg): none meets both targets",
)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["igea", "nefertiti", pytest.param("spot", marks=_SPOT_RMS)])
def test_level5_rms_within_target(name):
    # nefertiti measured 0.048 % (input-to-wrap, 30-face base, 30,720 faces at level 5)
    m = level_metrics(real_mesh(name), wrap(name, 5).levels[5])
    assert m["rms"] <= MAX_RMS_L5


@pytest.mark.slow
@pytest.mark.parametrize("name", ["igea", "nefertiti", "spot"])
def test_level5_has_no_flips_and_no_thin_triangles(name):
    # minimum angles measured: igea 27, nefertiti 9.3, spot 7.1 degrees
    m = level_metrics(real_mesh(name), wrap(name, 5).levels[5])
    assert m["flips"] == 0
    assert m["min_angle_deg"] >= MIN_ANGLE_DEG
    # in space: measured igea 0, spot 0, nefertiti 12 of 30,720 triangles facing against the
    # input (it has 294 faces folded by more than 120 deg against a neighbour itself)
    assert m["normal_flips"] <= MAX_NORMAL_FLIPS * m["faces"]


#: the protrusion bounds of a level-5 wrap: Hausdorff distance (fraction of the bbox
#: diagonal), smallest angle (degrees), triangles facing against the input
PROTRUSION_HAUSDORFF, PROTRUSION_MIN_ANGLE_DEG = 0.01, 5.0

_MISSES_TIPS = pytest.mark.xfail(
    strict=True,
    reason="the two-disk sphere map squeezes long protrusions into specks of the sphere and "
    "the wrap misses their tips (level 5, measured: bunny Hausdorff 5.3%; the generated "
    "quadruped 6.0%, smallest angle 0.0005 deg, 812 triangles facing against the input); 4 "
    "rounds of stretch reweighting reach bunny's ear tips (1.4%) with slivers (0.17 deg) and "
    "27 triangles facing against the input, and leave the quadruped at 6.3%. Tried: base "
    "vertices at geodesic farthest points (the tips) on the sphere's hull, 3D edge midpoints "
    "projected from level 1, tangential relaxation, 3D Delaunay flips of the base: the "
    "smallest angle halves at every level at the leg roots",
)


@pytest.mark.slow
@pytest.mark.parametrize(
    "name",
    [
        "spot",
        pytest.param("bunny", marks=_MISSES_TIPS),
        pytest.param("quadruped", marks=_MISSES_TIPS),
    ],
)
def test_level5_keeps_protrusions(name):
    # spot measured: Hausdorff 0.85 %, smallest angle 7.1 deg, no triangle against the input
    if name == "quadruped":
        mesh = quadruped()
        res = shrink_wrap(mesh, levels=5)
    elif name == "bunny":
        mesh = fill_holes(real_mesh("bunny"))
        res = shrink_wrap(mesh, levels=5)
    else:
        mesh, res = real_mesh(name), wrap(name, 5)
    m = level_metrics(mesh, res.levels[5])
    assert m["hausdorff"] <= PROTRUSION_HAUSDORFF
    assert m["min_angle_deg"] >= PROTRUSION_MIN_ANGLE_DEG
    assert m["flips"] == 0
    assert m["normal_flips"] == 0


def test_normal_flips_count_triangles_facing_against_the_input():
    sphere = analytic_mesh("icosphere")
    res = shrink_wrap(sphere, levels=1)
    lv = res.levels[1]
    assert level_metrics(sphere, lv)["normal_flips"] == 0
    turned = dataclasses.replace(lv, faces=lv.faces[:, ::-1].copy())
    assert level_metrics(sphere, turned)["normal_flips"] == len(lv.faces)


@pytest.mark.parametrize("name", ["nefertiti", "spot"])
def test_surface_phase_projects_along_the_normals(name):
    # measured: the first ray hit is taken for > 99.7 % of the projections
    res = wrap(name, 5)
    for lv in res.levels:
        m = level_metrics(real_mesh(name), lv)
        if lv.phase == "surface":
            assert m["ray_fraction"] >= 0.95
        else:
            assert m["ray_fraction"] is None


@pytest.mark.parametrize("name", ["igea", "nefertiti"])
def test_levels_have_subdivision_connectivity_and_lie_on_the_input(name):
    res = wrap(name, 5)
    mesh = real_mesh(name)
    nf0 = len(res.base.faces)
    for lv in res.levels:
        assert lv.faces.shape == (nf0 * 4**lv.level, 3)
        assert lv.mesh.is_closed and lv.mesh.genus == 0
        d = mesh.closest_points(lv.vertices).distance
        assert d.max() <= tol.length(mesh, tol.ON_SURFACE, scale="bbox_diagonal")
        assert_allclose(mesh.xyz(lv.points), lv.vertices)


def test_surface_phase_runs_and_keeps_the_map_bijective():
    opts = WrapOptions(min_switch_level=1, switch_tightness=10.0)
    res = shrink_wrap(real_mesh("spot"), opts, levels=3, smap=smap("spot"))
    assert res.switch_level == 2
    assert [lv.phase for lv in res.levels] == ["base", "parameter", "surface", "surface"]
    for lv in res.levels:
        assert (spherical_orientation(lv.sphere, lv.faces) > 0).all()


def test_metrics_report_has_the_issue_figures():
    rep = wrap_report(wrap("igea", 5))
    assert rep["sphere_map"]["method"] == "tutte"
    assert rep["base"]["faces"] <= MAX_BASE_FACES
    assert rep["base"]["cell_area_max"] / rep["base"]["cell_area_min"] <= MAX_CELL_RATIO
    assert [lv["level"] for lv in rep["levels"]] == list(range(6))
    for lv in rep["levels"]:
        assert lv["flips"] == 0 and lv["normal_flips"] >= 0
        assert 0 < lv["min_angle_deg"] < 60 and 1 <= lv["mean_aspect"] <= lv["max_aspect"]
        assert 0 < lv["rms"] < lv["hausdorff"] < 1
    rms = [lv["rms"] for lv in rep["levels"]]
    assert all(b < a for a, b in itertools.pairwise(rms))
    for sch in ("loop", "butterfly"):
        r = rep["reconstruction"][sch]
        assert r["0%"] > r["1%"] > r["3%"] > r["10%"] > 0


def test_fill_holes_closes_the_bunny_and_it_wraps():
    bunny = real_mesh("bunny")
    closed = fill_holes(bunny)
    assert closed.is_closed and closed.genus == 0
    assert_allclose(closed.vertices[: bunny.n_vertices], bunny.vertices)
    assert_array_equal(closed.faces[: bunny.n_faces], bunny.faces)
    # five holes of 22 to 80 edges: patches of triangles about as large as the mesh's
    new = closed.faces[bunny.n_faces :]
    assert 300 < closed.n_vertices - bunny.n_vertices < 400  # 342
    edges = np.linalg.norm(closed.vertices[new] - closed.vertices[np.roll(new, 1, axis=1)], axis=2)
    assert 0.8 < edges.mean() / bunny.mean_edge_length < 1.5  # 1.16
    assert np.percentile(_smallest_angles(closed.vertices, new), 5) > 20.0  # 27.2 degrees
    res = shrink_wrap(closed, levels=2)
    assert (spherical_orientation(res.levels[-1].sphere, res.levels[-1].faces) > 0).all()


def _smallest_angles(V, F):
    """Each triangle's smallest angle, degrees."""
    out = []
    for k in range(3):
        u = V[F[:, (k + 1) % 3]] - V[F[:, k]]
        w = V[F[:, (k + 2) % 3]] - V[F[:, k]]
        out.append(np.arctan2(np.linalg.norm(np.cross(u, w), axis=1), (u * w).sum(axis=1)))
    return np.degrees(np.min(out, axis=0))


def test_fill_holes_continues_a_sphere_over_a_cut_cap():
    # a cap of 40 degrees cut from a unit sphere: the thin-plate fill bulges out with it, the
    # least-area patch alone stays near the cut's plane (1 - cos 40 = 0.23 below the pole)
    sphere = icosphere(4)
    V, F = sphere.vertices, sphere.faces
    cap = V[F].mean(axis=1)[:, 2] > np.cos(np.radians(40.0))
    keep = np.unique(F[~cap])
    remap = np.full(len(V), -1)
    remap[keep] = np.arange(len(keep))
    cut = Mesh(V[keep], remap[F[~cap]])
    assert len(cut.boundary_loops) == 1
    flat = fill_holes(cut, fair=False)
    fair = fill_holes(cut)
    for m in (flat, fair):
        assert m.is_closed and m.genus == 0
    r_flat = np.linalg.norm(flat.vertices[cut.n_vertices :], axis=1)
    r_fair = np.linalg.norm(fair.vertices[cut.n_vertices :], axis=1)
    assert r_flat.min() < 0.8  # 0.77
    dev = np.abs(r_fair - 1.0)
    assert dev.max() < 0.06 and dev.mean() < 0.02, (dev.max(), dev.mean())  # 0.050, 0.017


def test_fill_holes_of_a_scan_whose_rim_vertices_are_joined_outside_the_hole():
    # nefertiti_fraunhofer's one hole (516 edges, the cut under the bust) has rim vertices
    # joined by edges of the mesh: no fill triangle may repeat one (the mesh would have an
    # edge of three faces, refused on construction)
    scan = real_mesh("nefertiti_fraunhofer")
    closed = fill_holes(scan)
    assert closed.is_closed and closed.genus == 0
    assert closed.vertex_colors is not None and len(closed.vertex_colors) == closed.n_vertices


def test_fill_holes_refuses_large_holes():
    with pytest.raises(errors.TopologyError, match="larger than max_edges"):
        fill_holes(real_mesh("nefertiti_fraunhofer"), max_edges=100)


def test_wrap_rejects_a_handle():
    with pytest.raises(errors.TopologyError, match="genus"):
        shrink_wrap(analytic_mesh("torus"), levels=1)


def test_wrap_refuses_levels_past_the_face_limit(monkeypatch):
    # every level has four times the faces of the last (spot at 12 levels ran 5 minutes unended;
    # refused before the base is made, over the fewest base faces any start gives: 8)
    from meshfit.shrinkwrap import wrap as w

    sphere = analytic_mesh("icosphere")
    says = r"over at least 8 base faces make at least 134,217,728 faces.*9 levels or fewer"
    with pytest.raises(errors.InputError, match=says):
        shrink_wrap(sphere, levels=12)
    # checked again with the base's own face count once it is made
    monkeypatch.setattr(w, "WRAP_MAX_FACES", 20 * 4**2)
    res = shrink_wrap(sphere, WrapOptions(base_faces=20), levels=2)
    assert len(res.levels[2].faces) == 320
    with pytest.raises(errors.InputError, match=r"2 levels over 40 base faces make 640 faces"):
        shrink_wrap(sphere, levels=2, base_options=BaseOptions(max_faces=40, min_faces=40))


def test_base_faces_and_base_options_set_one_budget():
    from meshfit.shrinkwrap import sphere_map

    sphere = analytic_mesh("icosphere")
    sm = sphere_map(sphere)
    # without base options the wrap's base_faces is the budget; with them, their max_faces
    want = base_mesh(sm, BaseOptions(max_faces=40, min_faces=40))
    for opts, bopts in [
        (WrapOptions(base_faces=40), BaseOptions(max_faces=40, min_faces=40)),
        (None, BaseOptions(max_faces=40, min_faces=40)),
    ]:
        got = shrink_wrap(sphere, opts, levels=0, smap=sm, base_options=bopts).base
        assert_array_equal(got.sphere, want.sphere)
        assert_array_equal(got.faces, want.faces)
    got = shrink_wrap(sphere, WrapOptions(base_faces=40), levels=0, smap=sm).base
    assert_array_equal(got.sphere, base_mesh(sm, BaseOptions(max_faces=40)).sphere)
    # two different budgets are refused rather than one silently dropped
    with pytest.raises(errors.InputError, match=r"base_faces=40\) disagrees with BaseOptions"):
        shrink_wrap(sphere, WrapOptions(base_faces=40), smap=sm, base_options=BaseOptions())
    with pytest.raises(errors.InputError, match="base_options must be a BaseOptions"):
        shrink_wrap(sphere, smap=sm, base_options={"seed": 1})  # type: ignore[arg-type]


def test_wrap_of_a_sphere_is_regular_and_close():
    sphere = analytic_mesh("icosphere")  # 1,280 faces, radius 1
    res = shrink_wrap(sphere, levels=3)
    m = level_metrics(sphere, res.levels[3])
    assert m["flips"] == 0
    assert m["min_angle_deg"] >= 20.0
    assert m["hausdorff"] <= 0.01
    r = np.linalg.norm(res.levels[3].vertices, axis=1)
    assert r.max() <= 1.0 + 1e-9 and r.min() >= 0.98  # on the flat-faced icosphere


def test_base_mesh_from_the_geodesic_polyhedron():
    b = base_mesh(smap("nefertiti"), BaseOptions(start_subdivisions=1, min_faces=80))
    assert 80 <= len(b.faces) <= MAX_BASE_FACES
    assert b.area_ratio <= MAX_CELL_RATIO


@pytest.mark.slow
@pytest.mark.xfail(
    strict=True,
    reason="base seed 1 (32 faces, max/min cell area 2.09): level-5 RMS 0.060%, min angle 0.46 "
    "deg; the base's smallest angle is 5.9 deg (seed 0: 6.4) but the levels' minimum halves at "
    "every level (4.4, 2.9, 1.7, 0.8, 0.46 deg; 362 triangles under 5 deg at level 5, 319 of "
    "them in two neighbouring base faces) and the clean-up does not recover it",
)
def test_level5_targets_hold_for_another_base_seed():
    mesh = real_mesh("nefertiti")
    res = shrink_wrap(mesh, levels=5, smap=smap("nefertiti"), base_options=BaseOptions(seed=1))
    m = level_metrics(mesh, res.levels[5])
    assert m["rms"] <= MAX_RMS_L5
    assert m["min_angle_deg"] >= MIN_ANGLE_DEG


def test_a_stretched_sphere_map_lets_the_wrap_reach_the_ear_tips():
    # the mean-value map squeezes bunny's ears into 0.4% of the sphere, and the wrap misses
    # their tips; with 4 rounds of stretch reweighting it reaches them (level 4: Hausdorff
    # 7.4% -> 3.3% of the bbox diagonal, RMS 0.80% -> 0.22%; the highest vertex 0.1760 ->
    # 0.1869, the tips at 0.1873), with less even triangles
    mesh = fill_holes(real_mesh("bunny"))
    got = {}
    for k in (0, 4):
        res = shrink_wrap(mesh, WrapOptions(sphere_stretch=k), levels=4)
        top = res.levels[-1]
        m = level_metrics(mesh, top)
        far = top.vertices[:, 1].max()  # the highest wrap vertex: the ear tips reach 0.1873
        got[k] = (m["hausdorff"], m["rms"], far, m["min_angle_deg"])
    (h0, r0, y0, _), (h4, r4, y4, a4) = got[0], got[4]
    assert h0 > 0.04 and h4 < 0.6 * h0, got
    assert r4 < 0.4 * r0, got
    top_y = mesh.vertices[:, 1].max()
    assert top_y - y4 < 0.3 * (top_y - y0), (top_y, y0, y4)
    assert 0 < a4 < MIN_ANGLE_DEG  # the price: thin triangles
