"""Automatic layouts of meshes of any topology (:mod:`meshfit.layout.regions`), sharp creases
on patch boundaries, and the one-call fit of every kind of mesh."""

from __future__ import annotations

from functools import cache

import numpy as np
import pytest

from meshfit.errors import InputError
from meshfit.layout import extract_patches, regions
from meshfit.layout.auto import LayoutOptions, auto_layout
from meshfit.layout.regions import crease_corners, crease_edges, region_layout
from meshfit.mesh import Mesh, load_mesh
from meshfit.pipeline import FitOptions, fit

from .. import shapes
from ..conftest import mesh_path

#: the issue's bounds on every fit (fractions of the bbox diagonal; degrees)
DISPLACED_RMS = 5e-4
DISPLACED_HAUSDORFF = 5e-3
SMOOTH_SEAM_DEG = 2.0


def _inside_out() -> Mesh:
    s = shapes.icosphere(3)
    return Mesh.from_arrays(s.vertices, s.faces[:, ::-1], repair=True, name="inside_out")


GENERATED = {
    "torus": lambda: shapes.tori(1, edge=0.12),
    "double_torus": lambda: shapes.tori(2, edge=0.12),
    "genus3_solid": lambda: shapes.box_with_holes(3),
    "cad_part": shapes.cad_part,
    "joined_solids": shapes.joined_solids,
    "open_cylinder": shapes.cylinder,
    "disk": shapes.disk,
    "hemisphere": lambda: shapes.hemisphere(5),
    "sharp_cube": shapes.cube,
    "rounded_cube": lambda: shapes.cube(rounded=0.3, n=20),
    "two_spheres": shapes.two_spheres,
    "dirty_merge": lambda: Mesh.from_arrays(*shapes.dirty_sphere(), repair=True, name="dirty"),
    "inside_out_sphere": _inside_out,
}


@cache
def generated(name: str) -> Mesh:
    return GENERATED[name]()


@pytest.mark.parametrize("name", sorted(GENERATED))
def test_every_kind_of_mesh_is_laid_out(name):
    mesh = generated(name)
    layout = auto_layout(mesh)  # checked: every patch a disk bounded by its four sides
    patches = extract_patches(mesh, layout)
    assert len(patches) == layout.n_patches >= 4
    # every face belongs to a patch
    assert sum(p.mesh.n_faces for p in patches) >= mesh.n_faces


_FITS: dict[str, dict] = {}


def _fit(name: str, tmp: str) -> dict:
    """The one-call fit of a generated shape, made once for all the tests that read it."""
    if name not in _FITS:
        _FITS[name] = fit(generated(name), options=FitOptions(formats=(), report=False)).summary
    return _FITS[name]


#: measured gaps of the one-call fit (strict xfails; remove when fixed)
KNOWN_FOLDS = {
    "genus3_solid": "13 folded spring cells in 2 patches on the top face beside a hole: "
    "the cell boundaries between two top-face cells meet the hole's rim at glancing "
    "angles, so one cell has a corner of 7 to 30 degrees there (its quads keep a 12 "
    "degree corner) and the other a reflex one, which a chord now splits",
}


KNOWN_FOLDS["cad_part"] = (
    "7 folded spring cells in 3 patches, on the even remesh the fit makes of this CAD "
    "tessellation (its needle triangles gave 26 in 13 patches; a 152K-face version 99 folds, "
    "1 after an even remesh, and 1,258 with its edges split shorter, still needles): one "
    "patch turns back 180 degrees at a corner beside a hole's rim"
)


#: measured gaps of the displaced surface's Hausdorff bound (strict xfails)
KNOWN_HAUSDORFF: dict[str, str] = {}


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(GENERATED))
def test_every_kind_of_mesh_fits_within_the_bounds(name, tmp_path_factory):
    s = _fit(name, str(tmp_path_factory.mktemp(name)))
    d = s["errors"]["displaced"]
    assert d["rms"] <= DISPLACED_RMS
    # against the input: through the even remesh where the fit worked on one
    assert d["hausdorff"] + s["mesh"].get("remeshed", {}).get("distance", 0) <= DISPLACED_HAUSDORFF
    assert s["seams"]["spline_normal_jump_inner_max_deg"] <= SMOOTH_SEAM_DEG
    # the summary says which route laid it out
    assert s["layout"]["route"] in ("sphere", "regions", "sphere -> regions")
    assert (s["layout"]["route"] == "sphere") == ("cells" not in s["layout"])


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(GENERATED))
def test_every_kind_of_mesh_fits_without_folded_cells(name, tmp_path_factory, request):
    if name in KNOWN_FOLDS:
        request.applymarker(pytest.mark.xfail(strict=True, reason=KNOWN_FOLDS[name]))
    s = _fit(name, str(tmp_path_factory.mktemp(name)))
    folded = {p["patch"]: p["folded"] for p in s["patches"] if p["folded"]}
    assert not folded


@cache
def _real_fit(name: str, tmp: str) -> dict:  # (one test reads each)
    mesh = load_mesh(mesh_path(name), repair=True)  # the command line's default
    return fit(mesh, options=FitOptions(formats=("obj",), report=False), out=tmp).summary


@pytest.mark.slow
@pytest.mark.parametrize("name", ["kitten", "rocker-arm", "nefertiti_fraunhofer"])
def test_scans_of_any_topology_fit_with_no_options(name, tmp_path_factory, request):
    """kitten and rocker-arm are genus 1, nefertiti_fraunhofer is open with back-to-back
    faces (repaired by default); igea, nefertiti and spot: tests/test_pipeline.py."""
    from ..test_outputs import assert_obj_watertight

    tmp = tmp_path_factory.mktemp(name)
    s = _real_fit(name, str(tmp))
    # the OBJ's patches share their boundary vertices (the input's boundary stays open)
    assert_obj_watertight(tmp / f"{name}.obj", closed=name != "nefertiti_fraunhofer")
    d = s["errors"]["displaced"]
    assert d["rms"] <= DISPLACED_RMS
    assert s["seams"]["spline_normal_jump_inner_max_deg"] <= SMOOTH_SEAM_DEG
    assert not any(f["folded"] for f in s["patches"]) or name in KNOWN_FOLDS
    if name in KNOWN_HAUSDORFF:
        request.applymarker(pytest.mark.xfail(strict=True, reason=KNOWN_HAUSDORFF[name]))
    assert d["hausdorff"] <= DISPLACED_HAUSDORFF
    if name in KNOWN_FOLDS:
        request.applymarker(pytest.mark.xfail(strict=True, reason=KNOWN_FOLDS[name]))
    assert not {p["patch"]: p["folded"] for p in s["patches"] if p["folded"]}


@pytest.mark.slow
def test_bunny_is_laid_out_as_it_is(bunny_fit):
    """Open (five holes) with unreferenced vertices, repaired by default: every hole's rim
    runs along patch boundaries, nothing is filled (its fit: benchmarks/layout.py and
    tests/test_outputs.py, whose automatic layout this reads)."""
    mesh, result, _ = bunny_fit
    # the fit's layout is auto_layout(mesh) with the default options, on this mesh
    assert FitOptions().layout == LayoutOptions()
    assert result.summary["mesh"]["faces"] == mesh.n_faces
    layout = result.layout
    patches = extract_patches(mesh, layout)
    assert len(patches) == layout.n_patches
    rims = sum(len(p.mesh.boundary_loops) for p in patches)
    assert rims == layout.n_patches  # every patch a disk


def test_repairs_are_noted_in_the_summary(tmp_path):
    s = _fit("dirty_merge", str(tmp_path))
    assert any("split" in n and "duplicate face" in n for n in s["notes"])
    s = _fit("inside_out_sphere", str(tmp_path / "b"))
    assert any("inside out: 1 component" in n for n in s["notes"])


def _sharp_brute(mesh: Mesh, angle: float) -> tuple[np.ndarray, np.ndarray]:
    """Edges whose two faces' normals turn by more than ``angle`` degrees, face pair by
    face pair (the definition), and the edges within round-off of the angle."""
    faces_of: dict[tuple[int, int], list[int]] = {}
    for f, tri in enumerate(mesh.faces.tolist()):
        for k in range(3):
            a, b = tri[k], tri[(k + 1) % 3]
            faces_of.setdefault((min(a, b), max(a, b)), []).append(f)
    n = mesh.face_normals
    limit = np.cos(np.radians(angle))
    sharp = np.zeros(mesh.edges.shape[0], dtype=bool)
    close = np.zeros(mesh.edges.shape[0], dtype=bool)
    for e, (a, b) in enumerate(mesh.edges.tolist()):
        fs = faces_of[(a, b)]
        if len(fs) == 2:
            c = float(n[fs[0]] @ n[fs[1]])
            sharp[e] = c < limit
            close[e] = abs(c - limit) < 1e-12
    return sharp, close


@pytest.mark.parametrize("name", ["sharp_cube", "open_cylinder", "genus3_solid"])
@pytest.mark.parametrize("chunk", [1, 97, 1 << 20])
def test_sharp_edges_are_the_face_pairs_turning_past_the_angle(name, chunk, monkeypatch):
    """Whatever the chunk of edges taken at a time, boundary edges included."""
    mesh = generated(name)
    monkeypatch.setattr(regions, "SHARP_CHUNK", chunk)
    for angle in (5.0, 40.0):
        want, close = _sharp_brute(mesh, angle)
        got = regions.sharp_edges(mesh, angle)
        assert np.array_equal(got[~close], want[~close]), (name, angle)
        if name != "open_cylinder":
            assert want.any()


def test_sharp_cube_edges_lie_on_crease_curves():
    cube = generated("sharp_cube")
    sharp = crease_edges(cube)
    ends = cube.vertices[cube.edges[sharp]]
    # the 12 edges of the cube and nothing else: two coordinates at +-1 on every sharp edge
    on_edge = (np.isclose(np.abs(ends), 1.0).sum(axis=2) >= 2).all(axis=1)
    assert on_edge.all()
    assert np.linalg.norm(ends[:, 0] - ends[:, 1], axis=1).sum() == pytest.approx(24.0)
    corners = cube.vertices[crease_corners(cube, sharp)]
    assert np.allclose(np.abs(corners), 1.0) and len(corners) == 8
    layout = auto_layout(cube)
    crease = np.flatnonzero(layout.creases)
    xyz = np.concatenate([cube.xyz(layout.curves[c].points) for c in crease])
    assert (np.isclose(np.abs(xyz), 1.0, atol=1e-9).sum(axis=1) >= 2).all()
    length = sum(
        np.linalg.norm(np.diff(cube.xyz(layout.curves[c].points), axis=0), axis=1).sum()
        for c in crease
    )
    assert length == pytest.approx(24.0, rel=1e-9)
    # the cube's corners are layout corners
    cxyz = cube.xyz(layout.corners)
    for c in corners:
        assert np.linalg.norm(cxyz - c, axis=1).min() < 1e-9


def test_smooth_shapes_have_no_creases():
    assert not crease_edges(generated("rounded_cube")).any()
    assert not crease_edges(generated("torus")).any()
    assert not region_layout(generated("torus")).creases.any()


@pytest.mark.parametrize("noise", [0.2, 0.4])
def test_scan_noise_that_folds_the_triangles_makes_no_creases(noise):
    """Noise of a fifth to two fifths of an edge folds a sixth to two thirds of bunny's
    edges by more than the crease angle, in nets of loops a few edges long: no crease (at
    0.4 the layout made some 30,000 cells along them and the fit failed). A part's own
    creases, loops that bound its faces, are kept however coarse its tessellation."""
    bunny = load_mesh(mesh_path("bunny"), repair=True)
    rng = np.random.default_rng(3)
    scale = noise * bunny.edge_lengths.mean()
    noisy = Mesh(bunny.vertices + rng.normal(scale=scale, size=bunny.vertices.shape), bunny.faces)
    assert regions.sharp_edges(noisy, regions.CREASE_ANGLE).mean() > 0.15
    assert not crease_edges(noisy).any()
    for coarse in (shapes.cube(n=1), shapes.cube(n=2), shapes.cad_part()):
        sharp = regions.sharp_edges(coarse, regions.CREASE_ANGLE)
        assert np.array_equal(crease_edges(coarse), sharp)


def _noisy(mesh: Mesh, share: float, seed: int) -> Mesh:
    """``mesh`` with Gaussian noise of ``share`` mean edge lengths on every coordinate."""
    rng = np.random.default_rng(seed)
    scale = share * mesh.edge_lengths.mean()
    return Mesh(mesh.vertices + rng.normal(scale=scale, size=mesh.vertices.shape), mesh.faces)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_noise_that_folds_a_part_or_a_coarse_scan_makes_no_creases(seed):
    """Noise of a quarter edge folds a third of the edges of a cube and of spot by more
    than the crease angle. spot is coarse (an edge is some 2% of its diagonal), so the noise
    nets' loops pass the length tests: some 450 crease edges, and curves of the layout along
    them that crossed; on the cube the net clung to its own creases (800 edges, 135 of them
    the cube's). The median fold of their other edges (some 18 degrees) says it is noise."""
    for mesh in (shapes.cube(), load_mesh(mesh_path("spot"))):
        noisy = _noisy(mesh, 0.25, seed)
        assert regions.sharp_edges(noisy, regions.CREASE_ANGLE).mean() > 0.3
        assert not crease_edges(noisy).any()


def test_a_parts_creases_survive_rigid_motions_scalings_and_slight_noise():
    cube = shapes.cube()
    creases = crease_edges(cube)
    assert creases.sum() == 12 * 12  # its twelve edges, twelve mesh edges each
    rot = np.linalg.qr(np.random.default_rng(0).normal(size=(3, 3)))[0]
    for scale in (1e-3, 1.0, 1e3):
        moved = Mesh(scale * cube.vertices @ rot.T + [5.0, -2.0, 1.0], cube.faces)
        assert np.array_equal(crease_edges(moved), creases)
    for seed in (1, 2):
        assert np.array_equal(crease_edges(_noisy(cube, 0.05, seed)), creases)


@pytest.mark.parametrize("name", ["bunny", "kitten", "spot", "rocker-arm", "nefertiti", "igea"])
def test_clean_scans_fold_well_below_the_noise_gate(name, monkeypatch):
    """The median fold of a clean scan's non-sharp edges, against the exact median of its
    angles (the histogram's bins are a tenth of a degree): under two thirds of the gate;
    taken over every stride-th edge only, it moves by less than a degree."""
    mesh = load_mesh(mesh_path(name), repair=True)
    angle = regions.CREASE_ANGLE
    sharp, fold = regions._folds(mesh, angle, with_median=True)
    edges = mesh._edge_table
    two = np.flatnonzero(edges.edge_count == 2)
    fa = edges.order[edges.start[two]] // 3
    fb = edges.order[edges.start[two] + 1] // 3
    dots = np.clip((mesh.face_normals[fa] * mesh.face_normals[fb]).sum(1), -1.0, 1.0)
    folds = np.degrees(np.arccos(dots))
    assert np.array_equal(np.flatnonzero(sharp), two[folds > angle])
    exact = float(np.median(folds[folds <= angle]))
    assert exact <= fold <= exact + 2 * angle / regions.FOLD_BINS
    assert fold < (2 / 3) * regions.CREASE_NOISE * angle
    monkeypatch.setattr(regions, "FOLD_SAMPLE", 1 << 12)
    assert abs(regions._folds(mesh, angle, with_median=True)[1] - fold) < 1.0


def test_cone_normals_see_the_shape_through_scan_noise():
    """Noise of an edge length across a plane tilts its median vertex normal by some 38
    degrees and a third of them by over 45; after `CONE_SMOOTHING` rounds the median tilt
    is some 11 degrees and hardly any is over 45. The smoothing commutes with rotations and
    ignores scale."""
    plane = shapes.plane(40, jitter=0.3)
    rng = np.random.default_rng(0)
    z = rng.normal(scale=plane.edge_lengths.mean(), size=plane.n_vertices)
    noisy = Mesh(plane.vertices + np.outer(z, [0.0, 0.0, 1.0]), plane.faces)

    def tilt(n):
        return np.degrees(np.arccos(np.abs(n[:, 2])))

    assert np.median(tilt(noisy.vertex_normals)) > 30.0
    smooth = regions._cone_normals(noisy, regions.CONE_SMOOTHING)
    assert np.median(tilt(smooth)) < 15.0
    assert (tilt(smooth) > 45.0).mean() < 0.01
    rot = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    moved = Mesh(1e3 * noisy.vertices @ rot.T, noisy.faces)
    again = regions._cone_normals(moved, regions.CONE_SMOOTHING)
    np.testing.assert_allclose(again, smooth @ rot.T, atol=1e-9)


def test_scan_noise_does_not_multiply_the_cells():
    """Half an edge of noise on kitten turned so many vertex normals past the normal cone
    that its cells were split into some seven times the patches (1768 against 254); the
    cone test of a noisy mesh reads normals averaged over a few rings."""
    kitten = load_mesh(mesh_path("kitten"))
    clean = region_layout(kitten).n_patches
    noisy = _noisy(kitten, 0.5, 1)
    assert regions.noisy_folds(noisy) and not regions.noisy_folds(kitten)
    assert region_layout(noisy).n_patches <= 1.5 * clean


@pytest.mark.parametrize("seed", [2, 4])
def test_radii_follow_the_disc_map_on_a_noisy_scan(seed):
    """A quarter edge of noise on a small quadruped bends each cell's disc map sharply
    inside its folded faces. The radii from a cell's centre were joined straight across
    the sub-edges inside an input face, not along the map, and two of them crossed near
    the centre: these two seeds were refused with crossing curves. They now follow the map
    exactly (a sub-edge crossing between any two sub-triangles), as the map is one to one."""
    layout = region_layout(_noisy(shapes.quadruped(segments=24), 0.25, seed))
    assert layout.n_patches > 0


def test_both_components_get_patches():
    mesh = generated("two_spheres")
    layout = auto_layout(mesh)
    comp = mesh.face_components
    owner = {int(comp[p.face_parent[0]]) for p in extract_patches(mesh, layout)}
    assert owner == {0, 1}


def test_many_small_components_each_get_cells_beyond_the_patch_budget():
    """Specks and lone triangles get a cell or two each without taking cells from the body
    (a sphere with 60 specks was refused: its cell budget did not grow with them)."""
    mesh = shapes.debris()
    lay = region_layout(mesh)
    patches = extract_patches(mesh, lay)
    comp = mesh.face_components
    owner = np.array([int(comp[p.face_parent[0]]) for p in patches])
    assert set(owner.tolist()) == set(range(mesh.n_components))
    body = shapes.icosphere(3)
    assert (owner == 0).sum() == len(extract_patches(body, region_layout(body)))


def _asymmetric() -> Mesh:
    t = shapes.tori(1, edge=0.15)
    v = t.vertices.copy()
    v[:, 0] += 0.25 * v[:, 1] ** 2  # no symmetry: no tie decides the layout
    v[:, 2] *= 1.0 + 0.3 * (v[:, 0] > 0)
    return Mesh(v, t.faces, name="asymmetric_torus")


def _rotation(seed: int) -> np.ndarray:
    q, r = np.linalg.qr(np.random.default_rng(seed).normal(size=(3, 3)))
    q *= np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


@pytest.mark.slow
def test_rigid_motions_and_scalings_give_the_same_fit(tmp_path):
    """Defaults do not depend on a lucky orientation: the same patch count and errors
    within 20% (with a floor of 1e-5 of the diagonal) after a rotation, a translation and
    a uniform scaling."""
    base = _asymmetric()
    ref = fit(base, options=FitOptions(formats=(), report=False)).summary
    for k, scale in enumerate((1.0, 37.5)):
        v = base.vertices @ _rotation(k).T * scale + np.array([3.0, -7.0, 11.0]) * scale
        moved = Mesh(v, base.faces, name="moved")
        s = fit(moved, options=FitOptions(formats=(), report=False)).summary
        assert s["patches_total"] == ref["patches_total"]
        for kind in ("rms", "hausdorff"):
            a, b = s["errors"]["displaced"][kind], ref["errors"]["displaced"][kind]
            assert abs(a - b) <= 0.2 * b + 1e-5, (kind, a, b)


def test_small_components_are_named_and_dropped_on_request(tmp_path):
    from meshfit.mesh.components import component_shares, drop_small_components

    big, small = shapes.icosphere(3), shapes.icosphere(1, radius=0.05)
    v = np.vstack([big.vertices, small.vertices + np.array([3.0, 0.0, 0.0])])
    f = np.vstack([big.faces, small.faces + big.n_vertices])
    mesh = Mesh(v, f, name="with_debris")
    assert component_shares(mesh)[1] < 0.01
    kept, face_map = drop_small_components(mesh, 0.01)
    assert kept.n_components == 1 and kept.n_faces == big.n_faces
    assert (face_map[big.n_faces :] == -1).all()
    opts = FitOptions(formats=(), report=False, patches=24, drop_components_below=0.01)
    s = fit(mesh, options=opts).summary
    assert any("dropped 1 component below 1%" in n for n in s["notes"])
    assert s["mesh"]["faces"] == big.n_faces
    with pytest.raises(InputError, match="drop_components_below"):
        FitOptions(drop_components_below=1.5)


def test_cell_ends_across_a_crease_are_paired():
    """Ends of cells on one side of a crease only (corners with a straight angle across
    it) are moved onto the other side's: fewer of them, only crease vertices change cell,
    and every cell stays a disk."""
    from meshfit.layout import regions as R

    mesh = shapes.box_with_holes(2)
    sharp = crease_edges(mesh)
    work, parent = R._cut_open(mesh, sharp)
    corners = crease_corners(mesh, sharp)
    seeds, label, _, _ = R._cells(work, 20, 60)
    aligned = R._align_crease_cuts(work, label, parent, mesh, corners, seeds.size)

    def lone(lab):
        rims = R._rims(work, lab, parent, mesh)
        return sum(rims.lone(li, i) for li, i in rims.order)

    assert lone(aligned) < 0.75 * lone(label)
    changed = np.flatnonzero(aligned != label)
    on_rim = np.zeros(work.n_vertices, dtype=bool)
    on_rim[np.concatenate(work.boundary_loops)] = True
    assert changed.size and on_rim[changed].all()
    assert (R._euler_per_cell(work, aligned, seeds.size) == 1).all()


def _side_ratios(mesh: Mesh, layout) -> np.ndarray:
    """Per patch, its shortest side over its longest (lengths of the curves)."""
    lengths = np.array(
        [np.linalg.norm(np.diff(mesh.xyz(c.points), axis=0), axis=1).sum() for c in layout.curves]
    )
    sides = lengths[layout.patch_curves]
    return sides.min(axis=1) / sides.max(axis=1)


def test_short_sides_are_merged_into_corners_of_four_cells(monkeypatch):
    """Where four seeds lie nearly on a circle their cells share a short side; merged away,
    its two corners become one where four cells meet: each of the two cells that shared
    it gives one patch fewer, the network still cuts the mesh into disks (checked by
    ``region_layout``), and the stubbiest patch side grows."""
    from meshfit.layout import regions as R

    mesh = generated("double_torus")
    merged = region_layout(mesh, relax=False)
    monkeypatch.setattr(R, "SHORT_SIDE", 0.0)  # no side is shorter than nothing
    plain = region_layout(mesh, relax=False)
    fewer = plain.n_patches - merged.n_patches
    assert fewer > 0 and fewer % 2 == 0
    assert _side_ratios(mesh, merged).min() > 1.5 * _side_ratios(mesh, plain).min()


def test_chords_cut_polygons_until_no_straight_corner_is_left():
    """`_chord_ends` on every pattern of straight corners of 3- to 9-gons: a chord never
    joins neighbours or a corner a chord already ends at, two straight corners opposite
    each other are joined, and where it cuts, cutting on leaves no straight corner."""
    from itertools import product

    from meshfit.layout import regions as R

    assert R._chord_ends([True, False, False, True, False, False], [False] * 6) == (0, 3)
    assert R._chord_ends([False, True, False], [False] * 3) is None
    for n in range(3, 10):
        for straight in product([False, True], repeat=n):
            flags = [(s, False) for s in straight]
            cut = R._chord_ends(list(straight), [False] * n)
            if cut is None:
                continue
            todo = [flags]
            while todo:
                part = todo.pop()
                got = R._chord_ends([f[0] for f in part], [f[1] for f in part])
                if got is None:
                    assert not any(f[0] for f in part)
                    continue
                j, p = got
                m = len(part)
                assert part[j][0] and not part[p][1] and (p - j) % m not in (0, 1, m - 1)
                todo += R._parts(part, j, p)


def test_straight_corners_at_creases_are_joined_by_chords(tmp_path_factory, monkeypatch):
    """Cells on the two sides of the sharp cube's edges are grown apart; a cell end on one
    side only was a patch corner of 180 degrees across the edge. Joined by a chord to the
    opposite corner, every patch corner is below 150 degrees; without the chords (no
    corner counts as straight) the layout has fewer patches and straight corners."""
    from meshfit.layout import regions as R

    s = _fit("sharp_cube", str(tmp_path_factory.mktemp("sharp_cube")))
    assert max(a for p in s["patches"] for a in p["corner_angles"]) < R.STRAIGHT_CORNER
    mesh = generated("sharp_cube")
    chords = region_layout(mesh, relax=False)
    monkeypatch.setattr(R, "STRAIGHT_CORNER", 360.0)
    plain = region_layout(mesh, relax=False)
    assert chords.n_patches > plain.n_patches
    s = fit(mesh, options=FitOptions(formats=(), report=False)).summary
    assert max(a for p in s["patches"] for a in p["corner_angles"]) > 170.0


def test_a_mesh_too_small_for_one_patch_is_refused_with_the_reason():
    tet = Mesh(
        np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=float),
        np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]),
        name="tet",
    )
    with pytest.raises(InputError, match="tet has 4 faces: an automatic layout needs at least"):
        auto_layout(tet)


def test_the_chord_search_has_a_budget():
    """A cell of many straight corners that cannot all be cleared: the search looks at no
    more than `CHORD_SEARCH` parts (it was exponential in the cell's sides), and still
    returns a chord."""
    from meshfit.layout import regions as R

    n = 32
    flags = tuple((k < n - 2, False) for k in range(n))
    memo: dict = {}
    assert R._chord_search(flags, memo, [R.CHORD_SEARCH]) is not None
    assert len(memo) <= R.CHORD_SEARCH + n
