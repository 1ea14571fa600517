"""The browser side of ``meshfit ui``: viser scene and panels, thin glue over :class:`Session`.

Every panel control calls one :class:`meshfit.ui.state.Session` method and redraws; all
geometry work happens there. viser serves its three.js client from the installed wheel; the
server binds to 127.0.0.1 unless told otherwise.
"""

from __future__ import annotations

import threading
import time
import traceback
from pathlib import Path

import numpy as np

from meshfit._words import plural
from meshfit.errors import MeshfitError
from meshfit.mesh import Mesh
from meshfit.ui.files import LAYOUT_SUFFIXES, FilePolicy, mesh_from_upload
from meshfit.ui.state import Session

__all__ = ["App"]

_REGION_OK = (80, 190, 110)
_REGION_BAD = (225, 80, 70)
_BOUNDARY = (20, 20, 230)
_FEATURE = (230, 120, 20)
_SELECTED = (250, 220, 0)
_STROKE = (240, 40, 200)

#: what :meth:`App._run` returns when the action was refused
FAILED = object()


def _error_colors(err: np.ndarray) -> np.ndarray:
    """Blue (0) to red (max) per value, ``(n, 3) uint8``."""
    m = float(err.max()) if err.size else 0.0
    t = err / m if m > 0 else np.zeros_like(err)
    return np.stack([255 * t, 80 * (1 - np.abs(2 * t - 1)), 255 * (1 - t)], axis=1).astype(np.uint8)


class App:
    """A running ``meshfit ui`` server.

    Parameters
    ----------
    session : Session
        The controller (holds the mesh, if one is open).
    policy : FilePolicy
        Which files the app may read and write.
    host : str
        Interface to bind; 127.0.0.1 (this machine only) by default.
    port : int
        TCP port; 0 picks a free one.
    layout_path : path, optional
        Default file of the layout save/load controls.
    """

    def __init__(
        self,
        session: Session,
        policy: FilePolicy,
        *,
        host: str = "127.0.0.1",
        port: int = 8080,
        layout_path: str | Path | None = None,
    ) -> None:
        import viser

        from meshfit.ui import guard

        guard.install()  # (requests from other origins are refused at the handshake)
        #: the per-run token an app bound beyond loopback asks for (None on loopback)
        self.token = None if host in guard.LOOPBACK_HOSTS else guard.new_token()
        self.session = session
        self.policy = policy
        self.lock = threading.RLock()
        self.server = viser.ViserServer(host=host, port=port, verbose=False)
        # viser can open a public tunnel through its share service when any client asks for
        # it; the app stays on the interface it was bound to: no share button, and the
        # request is refused on the server too (its handler looks the method up at call time)
        self.server.gui.configure_theme(show_share_button=False)
        self.server.request_share_url = self._refuse_share  # type: ignore[method-assign]
        self._cap_uploads()
        self.messages: list[str] = []
        self.selected: int | None = None
        self.edit_point: int | None = None
        self._gizmos: list = []
        self._pause = threading.Event()
        self._stopping = False
        self._levels_thread: threading.Thread | None = None
        self.preview_level = -1
        self._nodes: dict[str, list] = {}
        self._build_gui(layout_path)
        self.server.scene.on_click()(self._on_click)
        self.server.on_client_connect(self._frame_camera)
        self.redraw(mesh=True)

    def _frame_camera(self, client) -> None:
        """Look at the mesh from its front (+z), the mesh filling most of the view."""
        m = self.session.mesh
        if m is None:
            return
        lo, hi = m.bbox
        c = 0.5 * (lo + hi)
        client.camera.up_direction = (0.0, 1.0, 0.0)
        client.camera.position = tuple(c + np.array([0.0, 0.0, 0.9 * m.bbox_diagonal]))
        client.camera.look_at = tuple(c)  # after the position: keeps looking at the mesh

    # ------------------------------------------------------------------------ plumbing
    @property
    def port(self) -> int:
        return int(self.server.get_port())

    def url(self, host: str) -> str:
        """The address to open (with the token where the app asks for one)."""
        shown = f"[{host}]" if ":" in host else host
        return f"http://{shown}:{self.port}/" + (f"?token={self.token}" if self.token else "")

    def _cap_uploads(self) -> None:
        """Refuse an upload as its bytes arrive, not once it is whole in memory: one that
        declares more than the policy's cap is never buffered, and one whose parts pass the
        cap (a client that declared less) has its buffer dropped at the part that does.

        viser assembles uploads from parts in its GUI handlers; these two take their place
        in the server's handler registry and call them. They reach viser's private names
        (its upload handlers and transfer states), so tests/ui/test_guard.py holds the cap
        on the installed viser: a release that renames them fails there."""
        from viser import _messages

        gui = self.server.gui
        iface = gui._websock_interface
        start, part = gui._handle_file_transfer_start, gui._handle_file_transfer_part
        states = gui._current_file_upload_states
        cap = self.policy.max_upload

        def refuse(name: str, size: int) -> None:
            self.say(f"**refused:** upload {name!r} is over {size:,} bytes; the limit is {cap:,}")

        def capped_start(client_id, message) -> None:
            if message.size_bytes > cap:
                refuse(message.filename, message.size_bytes)
                return
            start(client_id, message)

        def capped_part(client_id, message) -> None:
            state = states.get(message.transfer_uuid)
            if state is not None and state["transferred_bytes"] + len(message.content) > cap:
                states.pop(message.transfer_uuid, None)
                refuse(state["filename"], cap)
                return
            part(client_id, message)

        iface.unregister_handler(_messages.FileTransferStartUpload, start)
        iface.unregister_handler(_messages.FileTransferPart, part)
        iface.register_handler(_messages.FileTransferStartUpload, capped_start)
        iface.register_handler(_messages.FileTransferPart, capped_part)

    def _refuse_share(self, verbose: bool = True) -> None:
        self.say("**refused:** sharing through a public tunnel is turned off in meshfit ui")
        return None

    def stop(self) -> None:
        self._stopping = True
        self.session.flush()
        self.server.stop()

    def say(self, text: str) -> None:
        """Show a message in the status line (and keep it for tests)."""
        self.messages.append(text)
        self.gui_message.content = text

    def _run(self, action, *args, redraw: bool = True, mesh: bool = False, **kw):
        """Call a session action; a meshfit error becomes a message, never a crash."""
        with self.lock:
            try:
                out = action(*args, **kw)
            except MeshfitError as exc:
                self.say(f"**refused:** {exc}")
                return FAILED
            except Exception as exc:  # keep the server alive; show what broke
                traceback.print_exc()
                self.say(f"**error:** {type(exc).__name__}: {exc}")
                return FAILED
            if redraw:
                self.redraw(mesh=mesh)
            return out

    # ------------------------------------------------------------------------ panels
    def _build_gui(self, layout_path) -> None:
        gui = self.server.gui
        s = self.session
        self.gui_message = gui.add_markdown("Open a mesh, then click on it to paint curves.")

        with gui.add_folder("Paint"):
            self.gui_mode = gui.add_dropdown(
                "Click mode", ("boundary", "feature", "edit", "view"), initial_value="boundary"
            )
            gui.add_button("Finish curve").on_click(
                lambda _: self._run(s.finish_curve) is not FAILED and self.say("curve finished")
            )
            gui.add_button("Cancel curve").on_click(
                lambda _: self._run(s.cancel_curve) is not FAILED and self.say("curve cancelled")
            )
            gui.add_button("Undo").on_click(
                lambda _: self.say("undone" if self._run(s.undo) is True else "nothing to undo")
            )
            gui.add_button("Redo").on_click(
                lambda _: self.say("redone" if self._run(s.redo) is True else "nothing to redo")
            )
            self.gui_curve = gui.add_number("Selected curve", initial_value=-1, step=1)
            self.gui_curve.on_update(lambda _: self._select(int(self.gui_curve.value)))
            gui.add_button("Delete curve").on_click(lambda _: self._on_delete())

        with gui.add_folder("Edit"):
            self.gui_section = gui.add_slider(
                "Edit section", min=2, max=60, step=1, initial_value=8
            )
            self.gui_fair = gui.add_slider(
                "Fairness", min=0.0, max=4.0, step=0.1, initial_value=1.0
            )
            self.gui_curv = gui.add_slider(
                "Curvature", min=0.0, max=4.0, step=0.1, initial_value=0.0
            )
            self.gui_iters = gui.add_slider(
                "Iterations", min=1, max=2000, step=1, initial_value=200
            )
            gui.add_button("Smooth curve").on_click(lambda _: self._on_curve_action("smooth"))
            gui.add_button("Snake step").on_click(lambda _: self._on_curve_action("step"))
            self.gui_ncontrol = gui.add_slider(
                "Control vertices", min=4, max=30, step=1, initial_value=8
            )
            gui.add_button("Fit space curve").on_click(lambda _: self._on_curve_action("space"))
            self.gui_color = gui.add_checkbox("Colour attraction", initial_value=False)
            self.gui_color_weight = gui.add_slider(
                "Colour weight", min=0.0, max=5.0, step=0.1, initial_value=1.0
            )
            self.gui_field = gui.add_dropdown(
                "Scalar field",
                (
                    "luminance",
                    "magnitude",
                    "red",
                    "green",
                    "blue",
                    "gaussian_curvature",
                    "mean_curvature",
                ),
                initial_value="luminance",
            )
            self.gui_sign = gui.add_dropdown("Attract to", ("high", "low"), initial_value="high")
            for h in (self.gui_color, self.gui_color_weight, self.gui_field, self.gui_sign):
                h.on_update(lambda _: self._on_color())

        with gui.add_folder("Layout"):
            gui.add_button("Check layout").on_click(lambda _: self._show_status())
            gui.add_button("Automatic layout").on_click(
                lambda _: self._run(s.auto_layout) is not FAILED and self._show_status()
            )
            self.gui_regions = gui.add_checkbox("Colour regions", initial_value=False)
            self.gui_regions.on_update(lambda _: self.redraw(mesh=True))
            self.gui_status = gui.add_markdown("")

        with gui.add_folder("Preview"):
            self.gui_patch = gui.add_number("Patch", initial_value=0, min=0, step=1)
            self.gui_level = gui.add_slider("Spring level", min=0, max=4, step=1, initial_value=0)
            gui.add_button("Spring mesh").on_click(lambda _: self._on_springs())
            gui.add_button("Run levels").on_click(lambda _: self._on_run_levels())
            gui.add_button("Pause / continue").on_click(lambda _: self._on_pause())
            self.gui_cu = gui.add_slider("Controls u", min=4, max=40, step=1, initial_value=8)
            self.gui_cv = gui.add_slider("Controls v", min=4, max=40, step=1, initial_value=8)
            self.gui_cu.on_update(lambda _: self._on_fit())
            self.gui_cv.on_update(lambda _: self._on_fit())
            gui.add_button("Fit B-spline").on_click(lambda _: self._on_fit())
            self.gui_fitinfo = gui.add_markdown("")
            self.gui_image = gui.add_image(np.zeros((8, 8, 3), np.uint8), label="Displacement")

        with gui.add_folder("Files"):
            default = "" if layout_path is None else str(layout_path)
            self.gui_layout_path = gui.add_text(
                "Layout file", initial_value=default or "layout.json"
            )
            gui.add_button("Save layout").on_click(lambda _: self._on_save())
            gui.add_button("Load layout").on_click(lambda _: self._on_load())
            self.gui_export = gui.add_text("Export folder", initial_value="export")
            gui.add_button("Export").on_click(lambda _: self._on_export())
            self.gui_progress = gui.add_progress_bar(0.0, visible=False)
            self.gui_upload = gui.add_upload_button("Open mesh", mime_type="*/*")
            self.gui_upload.on_upload(lambda _: self._on_upload())

    # ------------------------------------------------------------------------ drawing
    def _lift(self, xyz: np.ndarray, faces: np.ndarray) -> np.ndarray:
        """Lift points off the surface along their face normal so curves stay visible."""
        mesh = self.session.mesh
        return xyz + mesh.face_normals[faces] * (0.002 * mesh.bbox_diagonal)

    def redraw(self, *, mesh: bool = False) -> None:
        s = self.session
        scene = self.server.scene
        if s.mesh is None:
            return
        m = s.mesh
        if mesh:
            self._draw_mesh(m)
        self._clear("/curves")
        width = 0.004 * m.bbox_diagonal
        for i, pc in enumerate(s.curves):
            c = pc.curve.points
            x = self._lift(m.xyz(c), c.face)
            if len(x) < 2:
                continue
            col = _SELECTED if i == self.selected else (_BOUNDARY if pc.ends else _FEATURE)
            self._keep(
                "/curves",
                scene.add_line_segments(
                    f"/curves/c{i}", np.stack([x[:-1], x[1:]], axis=1), col, thickness=width
                ),
            )
        st = s.state.stroke
        if st is not None:
            pts = st.points()
            x = self._lift(m.xyz(pts), pts.face)
            if len(x) >= 2:
                self._keep(
                    "/curves",
                    scene.add_line_segments(
                        "/curves/stroke",
                        np.stack([x[:-1], x[1:]], axis=1),
                        _STROKE,
                        thickness=width,
                    ),
                )
        if len(s.corners):
            x = self._lift(m.xyz(s.corners), s.corners.face)
            self._keep(
                "/curves",
                scene.add_point_cloud(
                    "/curves/corners",
                    x,
                    np.full((len(x), 3), 20, np.uint8),
                    point_size=0.012 * m.bbox_diagonal,
                ),
            )
        self._draw_gizmos()
        self.gui_curve.value = -1 if self.selected is None else self.selected

    def _clear(self, prefix: str) -> None:
        for h in self._nodes.pop(prefix, []):
            h.remove()

    def _keep(self, prefix: str, handle) -> None:
        self._nodes.setdefault(prefix, []).append(handle)

    def _draw_mesh(self, m: Mesh) -> None:
        scene = self.server.scene
        self._clear("/mesh")
        if self.gui_regions.value and self.session.curves:
            st = self.session.status()
            if st.regions:
                rof = st.region_of_face
                for r in st.regions:
                    f = m.faces[rof == r.index]
                    if f.size:
                        shade = 0.75 + 0.25 * ((r.index * 7) % 5) / 4
                        col = np.asarray(_REGION_OK if r.valid else _REGION_BAD) * shade
                        self._keep(
                            "/mesh",
                            scene.add_mesh_simple(
                                f"/mesh/region{r.index}",
                                m.vertices,
                                f,
                                color=tuple(int(c) for c in col),
                            ),
                        )
                return
        if m.vertex_colors is not None:
            import trimesh

            tm = trimesh.Trimesh(
                m.vertices, m.faces, vertex_colors=m.vertex_colors[:, :3], process=False
            )
            self._keep("/mesh", scene.add_mesh_trimesh("/mesh/surface", tm))
        else:
            self._keep(
                "/mesh",
                scene.add_mesh_simple("/mesh/surface", m.vertices, m.faces, color=(200, 200, 200)),
            )

    def _draw_gizmos(self) -> None:
        for g in self._gizmos:
            g.remove()
        self._gizmos = []
        s = self.session
        if self.selected is None or self.selected >= len(s.curves):
            return
        pc = s.curves[self.selected]
        size = 0.05 * s.mesh.bbox_diagonal
        if pc.space is not None:
            for k, p in enumerate(pc.space.control_points):
                g = self.server.scene.add_transform_controls(
                    f"/gizmo/cv{k}",
                    scale=size,
                    position=tuple(p),
                    disable_rotations=True,
                    disable_sliders=True,
                )
                g.on_update(self._control_drag(k))
                self._gizmos.append(g)
        if self.edit_point is not None and self.edit_point < len(pc.curve):
            p = s.mesh.xyz(pc.curve.points[self.edit_point])[0]
            g = self.server.scene.add_transform_controls(
                "/gizmo/edit",
                scale=size,
                position=tuple(p),
                disable_rotations=True,
                disable_sliders=True,
            )
            g.on_update(self._edit_drag)
            self._gizmos.append(g)

    # ------------------------------------------------------------------------ events
    def _on_click(self, event) -> None:
        s = self.session
        if s.mesh is None:
            return
        mode = self.gui_mode.value
        o, d = event.ray_origin, event.ray_direction
        if mode in ("boundary", "feature"):
            what = self._run(s.click, o, d, kind=mode)
            if what is not FAILED:
                self.say(
                    f"{mode} pick: {what} ({plural(len(s.curves), 'curve')}, "
                    f"{plural(len(s.corners), 'corner')})"
                )
            return
        if mode == "edit":
            with self.lock:
                hit = s.pick(o, d)
            if hit is None:
                self.say("edit: the click missed the mesh")
                return
            x = s.mesh.xyz(hit)[0]
            near = s.nearest_sample(x)
            if near is not None and (self.edit_point is None or near[0] != self.selected):
                self.selected, self.edit_point = near
                self.say(f"curve {near[0]}: edit point {near[1]} (click the surface to pull it)")
                self.redraw()
            elif self.selected is not None and self.edit_point is not None:
                self._pull(x)
            else:
                self.say("edit: no curve near the click (click on a curve to pick an edit point)")
            return
        self.say("view mode: clicks do nothing")

    def _pull(self, target) -> None:
        s = self.session
        ok = self._run(
            s.edit_curve,
            self.selected,
            edit_index=self.edit_point,
            section=int(self.gui_section.value),
            target=np.asarray(target, dtype=np.float64),
            w_fair=float(self.gui_fair.value),
            w_curv=float(self.gui_curv.value),
        )
        if ok is not FAILED:
            self.say(f"curve {self.selected} edited at point {self.edit_point}")

    def _edit_drag(self, event) -> None:
        if getattr(event, "phase", "end") != "end":
            return
        self._pull(np.asarray(event.target.position, dtype=np.float64))

    def _control_drag(self, k: int):
        def cb(event) -> None:
            if getattr(event, "phase", "end") != "end" or self.selected is None:
                return
            self._run(
                self.session.move_control_point,
                self.selected,
                k,
                np.asarray(event.target.position, dtype=np.float64),
            )

        return cb

    def _select(self, i: int) -> None:
        n = len(self.session.curves)
        new = i if 0 <= i < n else None
        if new != self.selected:
            self.selected, self.edit_point = new, None
            self.redraw()

    def _on_delete(self) -> None:
        if self.selected is None:
            self.say("select a curve first (edit mode: click it)")
            return
        i, self.selected, self.edit_point = self.selected, None, None
        if self._run(self.session.delete_curve, i) is not FAILED:
            self.say(f"curve {i} deleted")

    def _on_curve_action(self, what: str) -> None:
        s = self.session
        if self.selected is None:
            self.say("select a curve first (edit mode: click it)")
            return
        kw = dict(w_fair=float(self.gui_fair.value), w_curv=float(self.gui_curv.value))
        if what == "smooth":
            it = self._run(s.smooth_curve, self.selected, max_iter=int(self.gui_iters.value), **kw)
            if it is not FAILED:
                self.say(f"curve {self.selected} smoothed ({it} iterations)")
        elif what == "step":
            move = self._run(s.snake_step, self.selected, **kw)
            if move is not FAILED:
                self.say(f"curve {self.selected}: one snake step, largest move {move:.3g}")
        else:
            sp = self._run(s.fit_space_curve, self.selected, n_control=int(self.gui_ncontrol.value))
            if sp is not FAILED:
                self.say(f"curve {self.selected}: space curve with {sp.n_control} control vertices")

    def _on_color(self) -> None:
        self._run(
            self.session.set_color_attraction,
            enabled=bool(self.gui_color.value),
            weight=float(self.gui_color_weight.value),
            field=str(self.gui_field.value),
            sign=1 if self.gui_sign.value == "high" else -1,
            redraw=False,
        )

    def _show_status(self) -> bool:
        st = self._run(self.session.status, redraw=False)
        if st is FAILED:
            return False
        if st.error:
            text = f"**not a layout:** {st.error}"
        else:
            n_ok = sum(r.valid for r in st.regions)
            rows = [f"**{n_ok} of {len(st.regions)} regions are four-sided patches**", ""]
            rows += [f"- region {r.index}: " + _region_text(r) for r in st.regions[:40]]
            text = "\n".join(rows)
        self.gui_status.content = text
        self.say(text.splitlines()[0])
        if self.gui_regions.value:
            self.redraw(mesh=True)
        return True

    # ------------------------------------------------------------------------ previews
    def _show_grid(self, grid) -> None:
        m = self.session.mesh
        x = np.asarray(grid.xyz)
        nu, nv = x.shape[:2]
        a = np.stack([x[:-1, :], x[1:, :]], axis=2).reshape(-1, 2, 3)
        b = np.stack([x[:, :-1], x[:, 1:]], axis=2).reshape(-1, 2, 3)
        self._clear("/preview/springs")
        self._keep(
            "/preview/springs",
            self.server.scene.add_line_segments(
                "/preview/springs",
                np.concatenate([a, b]),
                (0, 0, 0),
                thickness=0.002 * m.bbox_diagonal,
            ),
        )
        self.say(f"patch {grid.patch}: spring mesh level {grid.level}, {nu} x {nv} points")

    def _on_springs(self) -> None:
        g = self._run(
            self.session.spring_preview,
            int(self.gui_patch.value),
            level=int(self.gui_level.value),
            redraw=False,
        )
        if g is not FAILED:
            self._show_grid(g)
            self.preview_level = g.level

    def _on_run_levels(self) -> None:
        if self._levels_thread is not None and self._levels_thread.is_alive():
            return
        patch, top = int(self.gui_patch.value), int(self.gui_level.value)

        def work() -> None:
            for level in range(top + 1):
                while self._pause.is_set() and not self._stopping:
                    time.sleep(0.05)
                if self._stopping:
                    return
                g = self._run(self.session.spring_preview, patch, level=level, redraw=False)
                if g is FAILED:
                    return
                self._show_grid(g)
                self.preview_level = level

        self._levels_thread = threading.Thread(target=work, daemon=True)
        self._levels_thread.start()

    def _on_pause(self) -> None:
        if self._pause.is_set():
            self._pause.clear()
            self.say("spring levels: continue")
        else:
            self._pause.set()
            self.say("spring levels: paused")

    def _on_fit(self) -> None:
        s = self.session
        p = int(self.gui_patch.value)
        fit = self._run(
            s.fit_patch,
            p,
            controls=(int(self.gui_cu.value), int(self.gui_cv.value)),
            redraw=False,
        )
        if fit is FAILED:
            return
        from meshfit.springs import grid_triangles

        nu, nv = fit.spline_xyz.shape[:2]
        import trimesh

        tm = trimesh.Trimesh(
            fit.spline_xyz.reshape(-1, 3),
            grid_triangles(nu, nv),
            vertex_colors=_error_colors(fit.error.reshape(-1)),
            process=False,
        )
        self._clear("/preview/spline")
        self._keep("/preview/spline", self.server.scene.add_mesh_trimesh("/preview/spline", tm))
        img = self._run(s.displacement_image, p, redraw=False)
        if img is not FAILED:
            big = np.repeat(
                np.repeat(img, max(1, 128 // max(img.shape[:2])), 0),
                max(1, 128 // max(img.shape[:2])),
                1,
            )
            self.gui_image.image = big
        cp = fit.surface.control_points.shape
        self.gui_fitinfo.content = (
            f"patch {p}: {cp[0]} x {cp[1]} controls, RMS {fit.rms:.4g}, max "
            f"{float(fit.error.max()):.4g} (model units)"
        )
        self.say(self.gui_fitinfo.content)

    # ------------------------------------------------------------------------ files
    def _on_save(self) -> None:
        def save():
            p = self.policy.check(self.gui_layout_path.value, suffixes=LAYOUT_SUFFIXES, write=True)
            return self.session.save_layout(p)

        out = self._run(save, redraw=False)
        if out is not FAILED:
            self.say(f"layout saved to {out}")

    def _on_load(self) -> None:
        def load():
            p = self.policy.check(self.gui_layout_path.value, suffixes=LAYOUT_SUFFIXES)
            self.session.load_layout(p)
            return p

        self.selected = self.edit_point = None
        out = self._run(load)
        if out is not FAILED:
            self.say(f"layout loaded from {out} ({plural(len(self.session.curves), 'curve')})")

    def _on_export(self) -> None:
        def export():
            folder = self.policy.check_folder(self.gui_export.value)
            return self.session.export(
                folder,
                controls=(int(self.gui_cu.value), int(self.gui_cv.value)),
                progress=self._progress,
            )

        self.gui_progress.value = 0.0
        self.gui_progress.visible = True
        try:
            out = self._run(export, redraw=False)
        finally:
            self.gui_progress.visible = False
        if out is not FAILED:
            self.say(f"exported {len(out)} files to {self.gui_export.value}")

    def _progress(self, stage: str, done: int, total: int) -> None:
        """Fit progress from :func:`meshfit.fit` to the progress bar."""
        frac = done / total if total else 1.0
        self.gui_progress.value = float(100.0 * min(max(frac, 0.0), 1.0))
        self.gui_message.content = f"fitting: {stage} {done}/{total}"

    def _on_upload(self) -> None:
        f = self.gui_upload.value

        def open_upload():
            mesh = mesh_from_upload(f.name, f.content, max_bytes=self.policy.max_upload)
            s = self.session
            s.flush()
            s.autosave_path = None  # the old mesh's session file stays as it is
            s.set_mesh(mesh)
            # each mesh autosaves to its own file in the working folder (resumed if present)
            path = self.policy.workdir / f"{Path(mesh.name).stem}.session.json"
            s.resume_autosave(self.policy.allow(path))
            return mesh

        self.selected = self.edit_point = None
        mesh = self._run(open_upload, mesh=True)
        if mesh is not FAILED:
            self._clear("/preview/springs")
            self._clear("/preview/spline")
            self.say(f"opened {mesh.name}: {mesh.n_vertices} vertices, {mesh.n_faces} faces")
            if self.session.set_aside is not None:
                moved, why = self.session.set_aside
                self.say(f"{why}: moved it to {moved.name} and started a new session")


def _region_text(r) -> str:
    """A region's line in the layout status: "patch", a bulging or tapered patch's warning,
    or why the region is no patch."""
    from meshfit.layout.patch import BULGY, TAPERED

    if not r.valid:
        return f"**{r.reason}**"
    if r.bulge > BULGY:
        return (
            f"patch, **bulging** ({r.bulge:.3g} times the area of a square with its "
            "perimeter): its grid will crowd at the sides; add curves across it"
        )
    if r.taper > TAPERED:
        return (
            f"patch, **tapered** (a side {r.taper:.3g} times as long as the side opposite it): "
            "its grid cells will change size across it; move a corner or split it"
        )
    return "patch"
