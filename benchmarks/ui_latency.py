"""Benchmark: server-side latency of the web app's interactive actions on igea.

Every figure times a :class:`meshfit.ui.state.Session` action (what a browser event runs on
the server: the geometry call plus snapping, the undo snapshot and the autosave file write),
median of ``--repeats`` runs after a warm-up (numba compile excluded), each against a peer
timed in the same run:

* ``paint_segment`` (target <= 10 ms): ``Session.add_pick`` of the second pick of a stroke,
  ``--edges`` (default 50 and 200) mean edge lengths from the first; peer: the raw greedy
  graph path between the same vertices (:func:`meshfit.surface.greedy_path`, painting's first
  step); :func:`meshfit.curves.paint_curve` called directly is reported too, so the session's
  own overhead shows.
* ``snake_step`` (target <= 5 ms): ``Session.snake_step`` on a 1,000-point curve; peer:
  :func:`meshfit.curves.relax_snake` with ``max_iter=1`` called directly (no session).
* ``refit_patch`` (target <= 20 ms): ``Session.fit_patch`` of one patch's cached spring grid at
  a new control resolution (fit, evaluation on the grid and the error colours); peer:
  :func:`meshfit.bspline.fit_bspline` alone.
* ``spring_preview`` (target <= 100 ms): ``Session.spring_preview(level=0)`` of the patch
  closest to 25,000 vertices of a one-per-cube-face layout of igea (the session's previews
  and the kept square maps cleared each run: a cold preview); peer: one single-source
  Dijkstra over that patch's edge graph (``scipy.sparse.csgraph.dijkstra``), the unit of work
  of the level-0 iso-curves. A patch over
  :data:`meshfit.springs.preview.PREVIEW_MIN_VERTICES` gets its level-0 preview from a planar
  map made on a coarse copy (:func:`meshfit.springs.preview.coarse_level0`); also reported:
  the exact level 0 cold (``resample_patch(level=0)`` with its square map, the path used
  before), the preview's distance from it (max / median over the mean grid spacing and over
  the patch's bounding-box diagonal), level 1 cold, and level 1 right after level 0 (the
  coarse-to-fine preview; level 1 uses the exact square map, made there: level 0 no longer
  makes it).

* ``click_pick`` (target <= 50 ms): a click in the app's select mode on igea laid out one
  patch per cube face (:meth:`meshfit.ui.app.App._on_select_click`: the ray cast, the patch
  of the face hit, the highlight mesh sent to the scene, the camera framed, the figures);
  peer: the ray cast alone (``Mesh.ray_first_hit``).
* ``refit_preview`` (target <= 2 s): the whole-model re-fit preview of nefertiti (100K
  triangles, one patch per cube face) at new control counts once its spring meshes exist
  (``Session.refit_all`` and the view's redraw with the deviation colours); peer: the
  pipeline's own re-fit, :func:`meshfit.fit` resumed from its stage cache (spring meshes
  loaded, splines, maps, stitching and errors made again).
* ``first_paint`` (no target): from opening the page in Debian's chromium (headless,
  software WebGL) to the first frame showing the mesh, igea (270K triangles) in the app;
  peer: a plain viser server showing the same mesh.

Run: ``python benchmarks/ui_latency.py [--repeats 9] [--edges 50 200] [--only NAME...]``.
Prints JSON and writes ``benchmarks/results/ui_latency.json`` atomically (``--only`` keeps
the other figures of the file).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from _common import RESULTS, median_time, mesh_path, write_result
from scipy.sparse.csgraph import dijkstra

from meshfit.bspline import fit_bspline
from meshfit.curves import SnakeOptions, paint_curve, relax_snake, resample_curve
from meshfit.layout.cube import cube_layout
from meshfit.mesh import load_mesh
from meshfit.springs import SpringOptions, resample_patch
from meshfit.springs.planar import clear_map_cache
from meshfit.springs.preview import PREVIEW_MIN_VERTICES
from meshfit.surface import greedy_path
from meshfit.types import SurfaceCurve, SurfacePoints
from meshfit.ui.state import Session

TARGETS_MS = {
    "paint_segment": 10,
    "snake_step": 5,
    "refit_patch": 20,
    "spring_preview": 100,
    "click_pick": 50,
    "refit_preview": 2000,
    "first_paint": None,
}
FIGURES = ("paint", "snake", "patch", "click_pick", "refit_preview", "first_paint")
CHROMIUM = "/usr/bin/chromium"


def _ms(x: float) -> float:
    return round(1000 * x, 3)


def _figure(name: str, t: float, peer: float, peer_name: str, **extra) -> dict:
    target = TARGETS_MS[name]
    return {
        "median_ms": _ms(t),
        "target_ms": target,
        "meets_target": None if target is None else bool(1000 * t <= target),
        "peer": peer_name,
        "peer_median_ms": _ms(peer),
        "ratio_to_peer": round(t / peer, 3) if peer > 0 else None,
        **extra,
    }


def bench_paint(mesh, session: Session, edges: float, repeats: int) -> dict:
    v = mesh.vertices
    a = int(np.argmin(v[:, 1]))
    d = np.linalg.norm(v - v[a], axis=1)
    b = int(np.argmin(np.abs(d - edges * mesh.mean_edge_length)))
    pa = SurfacePoints.at_vertices(mesh.faces, [a])
    pb = SurfacePoints.at_vertices(mesh.faces, [b])
    session.add_pick(pa)
    start = session.state

    def paint():
        session.state = start
        session.add_pick(pb)

    paint()  # warm-up
    t, _ = median_time(paint, repeats)
    greedy_path(mesh, a, b)
    peer, _ = median_time(lambda: greedy_path(mesh, a, b), repeats)
    both = SurfacePoints.concatenate([pa, pb])
    paint_curve(mesh, both)
    direct, _ = median_time(lambda: paint_curve(mesh, both), repeats)
    n = len(session.state.stroke.points())
    session.state = start
    session.cancel_curve()
    return _figure(
        "paint_segment",
        t,
        peer,
        "greedy_path (raw graph path)",
        samples=n,
        chord_edges=round(float(d[b] / mesh.mean_edge_length), 1),
        paint_curve_direct_ms=_ms(direct),
        session_overhead_ms=_ms(t - direct),
    )


def bench_snake(mesh, session: Session, repeats: int) -> dict:
    v = mesh.vertices
    a = int(np.argmin(v[:, 1]))
    b = int(np.argmax(v[:, 1]))
    session.add_pick(SurfacePoints.at_vertices(mesh.faces, [a]))
    session.add_pick(SurfacePoints.at_vertices(mesh.faces, [b]))
    session.finish_curve()
    curve = session.curves[-1].curve
    if len(curve) < 1000:
        curve = resample_curve(mesh, curve, n=1000)
    curve1000 = SurfaceCurve(curve.points[np.arange(1000)], kind="boundary")
    i = len(session.curves) - 1
    session._replace_curve(i, curve1000, None)
    start = session.state

    def step():
        session.state = start
        session.snake_step(i)

    step()
    t, _ = median_time(step, repeats)
    one = SnakeOptions(max_iter=1)
    relax_snake(mesh, curve1000, one)
    peer, _ = median_time(lambda: relax_snake(mesh, curve1000, one), repeats)
    return _figure("snake_step", t, peer, "relax_snake(max_iter=1) direct", points=len(curve1000))


def bench_patch(mesh, session: Session, repeats: int) -> tuple[dict, dict]:
    t0 = time.perf_counter()
    session.set_layout(cube_layout(mesh, n=1))
    patches = session.patches()
    layout_s = time.perf_counter() - t0
    p = int(np.argmin([abs(q.mesh.n_vertices - 25_000) for q in patches]))
    nv = patches[p].mesh.n_vertices

    def clear(maps: bool) -> None:
        for k in [k for k in session._cache if isinstance(k, tuple) and k[0] == "springs"]:
            del session._cache[k]
        if maps:
            clear_map_cache()

    def preview(level: int = 0, maps: bool = True):
        clear(maps)
        return session.spring_preview(p, level=level)

    def next_level():  # level 0 shown (untimed), then level 1 with the map kept
        preview(0)
        clear(False)
        t0 = time.perf_counter()
        session.spring_preview(p, level=1)
        return time.perf_counter() - t0

    grid0 = preview()
    t_spring, _ = median_time(preview, repeats)
    t_level1, _ = median_time(lambda: preview(1), repeats)
    t_next = float(np.median([next_level() for _ in range(repeats)]))

    def exact_level0():
        clear_map_cache()
        return resample_patch(patches[p], SpringOptions(level=0, metrics=False)).final

    exact = exact_level0()
    t_exact, _ = median_time(exact_level0, repeats)
    E, G = np.asarray(exact.xyz), np.asarray(grid0.xyz)
    d = np.linalg.norm(G - E, axis=2)
    steps = np.concatenate([np.linalg.norm(np.diff(E, axis=k), axis=2).ravel() for k in (0, 1)])
    spacing = float(steps.mean())
    diag = float(patches[p].mesh.bbox_diagonal)
    pm = patches[p].mesh
    src = int(patches[p].sides[0][len(patches[p].sides[0]) // 2])
    graph = pm.edge_graph
    dijkstra(graph, indices=src)
    peer_spring, _ = median_time(lambda: dijkstra(graph, indices=src), repeats)
    spring = _figure(
        "spring_preview",
        t_spring,
        peer_spring,
        "scipy dijkstra, one source on the patch",
        patch_vertices=int(nv),
        grid=list(grid0.shape),
        layout_and_cut_s=round(layout_s, 2),
        coarse_copy_preview=bool(nv > PREVIEW_MIN_VERTICES),
        exact_level0_cold_ms=_ms(t_exact),
        offset_to_exact_level0={
            "max_over_spacing": round(float(d.max()) / spacing, 6),
            "median_over_spacing": round(float(np.median(d)) / spacing, 6),
            "max_over_diagonal": round(float(d.max()) / diag, 8),
            "median_over_diagonal": round(float(np.median(d)) / diag, 8),
        },
        level1_cold_ms=_ms(t_level1),
        level1_after_level0_ms=_ms(t_next),
    )
    grid = session.spring_preview(p, level=3)
    X = np.asarray(grid.xyz)
    sizes = [(8, 8), (12, 10), (16, 16), (10, 14)]
    session.fit_patch(p, controls=sizes[0])
    fit_bspline(X, controls=sizes[0])
    k = iter(range(10**9))
    t_fit, _ = median_time(
        lambda: session.fit_patch(p, controls=sizes[next(k) % len(sizes)]), repeats
    )
    k = iter(range(10**9))
    peer_fit, _ = median_time(lambda: fit_bspline(X, controls=sizes[next(k) % len(sizes)]), repeats)
    refit = _figure(
        "refit_patch",
        t_fit,
        peer_fit,
        "fit_bspline alone",
        grid=list(X.shape[:2]),
        controls_cycled=[list(c) for c in sizes],
    )
    return spring, refit


def bench_click_pick(mesh, repeats: int) -> dict:
    """A select-mode click on a patch of igea (one patch per cube face), no browser."""
    from meshfit.ui.app import App
    from meshfit.ui.files import FilePolicy

    with tempfile.TemporaryDirectory() as tmp:
        session = Session(mesh)
        session.set_layout(cube_layout(mesh, n=1))
        session.status()  # (the layout check a user runs before picking; cached)
        app = App(session, FilePolicy(tmp), port=0)
        try:
            c = 0.5 * (mesh.bbox[0] + mesh.bbox[1])
            origin = c + np.array([0.0, 0.0, 2.0 * mesh.bbox_diagonal])
            direction = np.array([0.0, 0.0, -1.0])
            hits = mesh.ray_first_hit(origin[None], direction[None])
            assert bool(hits.hit[0]), "the benchmark ray misses igea"
            app._on_select_click(origin, direction)
            t, _ = median_time(lambda: app._on_select_click(origin, direction), repeats)
            k = app.selected_patch
            n_faces = int(app._patch_faces(k).size)
            mesh.ray_first_hit(origin[None], direction[None])
            peer, _ = median_time(
                lambda: mesh.ray_first_hit(origin[None], direction[None]), repeats
            )
        finally:
            app.stop()
    return _figure(
        "click_pick",
        t,
        peer,
        "Mesh.ray_first_hit (the ray cast alone)",
        patch=k,
        patch_faces=n_faces,
        includes="ray cast, patch of the face, highlight mesh queued to the scene, camera, figures",
    )


def bench_refit_preview(repeats: int) -> dict:
    """The whole-model re-fit preview of nefertiti once its spring meshes exist."""
    import viser

    from meshfit.pipeline import FitOptions, fit
    from meshfit.ui.fitview import FitLayers

    mesh = load_mesh(mesh_path("nefertiti"))
    lo, hi = mesh.bbox
    # one patch per cube face, the cube's centre a tenth of the box up z (centred in the box
    # its curves cross on this bust)
    lay = cube_layout(mesh, n=1, center=0.5 * (lo + hi) + [0.0, 0.0, 0.1 * (hi - lo)[2]])
    session = Session(mesh)
    opts = FitOptions(formats=(), report=False)
    t0 = time.perf_counter()
    session.result = fit(mesh, lay, options=opts)  # (what Fit model keeps)
    first_fit_s = time.perf_counter() - t0
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        layers = FitLayers(server.scene, mesh)
        layers.draw(session.result)
        sizes = [(12, 12), (10, 14), (16, 16), (8, 8)]
        k = iter(range(10**9))

        def preview():
            result = session.refit_all(controls=sizes[next(k) % len(sizes)])
            layers.draw(result)

        preview()
        t, _ = median_time(preview, repeats)
    finally:
        server.stop()
    with tempfile.TemporaryDirectory() as tmp:
        fit(mesh, lay, options=opts, out=tmp)  # the stage cache the resumed runs read
        k = iter(range(10**9))

        def resumed():
            c = sizes[next(k) % len(sizes)]
            fit(mesh, lay, options=replace(opts, controls=c), out=tmp, resume=True)

        peer_runs = max(3, repeats // 3)
        peer, _ = median_time(resumed, peer_runs)
    return _figure(
        "refit_preview",
        t,
        peer,
        "meshfit.fit resumed from its stage cache (spring meshes loaded)",
        mesh="nefertiti",
        faces=mesh.n_faces,
        patches=len(session.result.patches),
        first_fit_s=round(first_fit_s, 2),
        controls_cycled=[list(c) for c in sizes],
        peer_runs=peer_runs,
    )


def _first_paint(url: str, browser, timeout: float = 300.0) -> float:
    """Seconds from opening ``url`` to a frame of the page whose middle holds the mesh
    (half the pixels of the view's middle off the white background)."""
    import io

    import png

    page = browser.new_page(viewport={"width": 1000, "height": 700})
    try:
        t0 = time.perf_counter()
        page.goto(url)
        while time.perf_counter() - t0 < timeout:
            shot = page.screenshot(clip={"x": 400, "y": 250, "width": 200, "height": 200})
            w, h, rows, _ = png.Reader(file=io.BytesIO(shot)).asRGBA8()
            img = np.vstack([np.frombuffer(r, np.uint8) for r in rows]).reshape(h, w, 4)
            if (img[:, :, :3].astype(int).sum(axis=2) < 720).mean() > 0.5:
                return time.perf_counter() - t0
            time.sleep(0.02)
        raise RuntimeError(f"no mesh on the page after {timeout} s")
    finally:
        page.close()


def bench_first_paint(mesh, repeats: int) -> dict:
    """First frame with igea on it: the app against a plain viser server."""
    import viser
    from playwright.sync_api import sync_playwright

    from meshfit.ui.app import App
    from meshfit.ui.files import FilePolicy

    args = ["--headless", "--no-sandbox", "--enable-unsafe-swiftshader", "--no-first-run"]
    runs = max(3, repeats // 3)
    with tempfile.TemporaryDirectory() as tmp, sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=args)
        try:
            app = App(Session(mesh), FilePolicy(tmp), port=0)
            try:
                ours = [_first_paint(f"http://127.0.0.1:{app.port}/", browser) for _ in range(runs)]
            finally:
                app.stop()
            plain = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
            try:
                plain.scene.add_mesh_simple("/mesh", mesh.vertices, mesh.faces)

                @plain.on_client_connect
                def _(client) -> None:  # the same view as the app's
                    lo, hi = mesh.bbox
                    c = 0.5 * (lo + hi)
                    client.camera.up_direction = (0.0, 1.0, 0.0)
                    client.camera.position = tuple(
                        c + np.array([0.0, 0.0, 0.9 * mesh.bbox_diagonal])
                    )
                    client.camera.look_at = tuple(c)

                url = f"http://127.0.0.1:{plain.get_port()}/"
                peer = [_first_paint(url, browser) for _ in range(runs)]
            finally:
                plain.stop()
        finally:
            browser.close()
    return _figure(
        "first_paint",
        float(np.median(ours)),
        float(np.median(peer)),
        "plain viser server with the same mesh (default scene settings)",
        runs_s=[round(x, 3) for x in ours],
        peer_runs_s=[round(x, 3) for x in peer],
        browser="Debian chromium, headless, software WebGL (SwiftShader)",
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=9)
    ap.add_argument(
        "--edges",
        type=float,
        nargs="+",
        default=[50.0, 200.0],
        help="chord lengths of the painted segment, mean edge lengths (default: 50 200)",
    )
    ap.add_argument(
        "--only",
        nargs="+",
        choices=FIGURES,
        help="measure only these figures (the file keeps the others' last values)",
    )
    args = ap.parse_args()
    todo = set(args.only or FIGURES)
    mesh = load_mesh(mesh_path("igea"))
    out: dict = {}
    path = RESULTS / "ui_latency.json"
    if args.only and path.is_file():
        out = json.loads(path.read_text())
    out.update(
        {
            "mesh": "igea",
            "vertices": mesh.n_vertices,
            "faces": mesh.n_faces,
            "repeats": args.repeats,
            "includes": "session action: geometry call, snapping, undo snapshot, autosave write",
        }
    )
    with tempfile.TemporaryDirectory() as tmp:
        session = Session(mesh, autosave=Path(tmp) / "igea.session.json")
        if "paint" in todo:
            out["paint_segment"] = {
                f"{e:g}_edges": bench_paint(mesh, session, e, args.repeats) for e in args.edges
            }
        if "snake" in todo:
            out["snake_step"] = bench_snake(mesh, session, args.repeats)
        if "patch" in todo:
            out["spring_preview"], out["refit_patch"] = bench_patch(mesh, session, args.repeats)
    if "click_pick" in todo:
        out["click_pick"] = bench_click_pick(mesh, args.repeats)
    if "refit_preview" in todo:
        out["refit_preview"] = bench_refit_preview(args.repeats)
    if "first_paint" in todo:
        out["first_paint"] = bench_first_paint(mesh, args.repeats)
    out["machine"] = {"cpus": os.cpu_count(), "python": platform.python_version()}
    write_result("ui_latency", out)


if __name__ == "__main__":
    main()
