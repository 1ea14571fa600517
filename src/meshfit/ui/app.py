"""The browser side of ``meshfit ui``: viser scene and panels, thin glue over :class:`Session`.

Every panel control calls one :class:`meshfit.ui.state.Session` method and redraws; all
geometry work happens there. A whole fit runs on a thread (progress per stage, cancel) and
is drawn by :class:`meshfit.ui.fitview.FitLayers`; clicks paint, edit, select patches and
curves, or paint on the selected patch's map, by the click mode. viser serves its three.js
client from the installed wheel; the server binds to 127.0.0.1 unless told otherwise.
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
from meshfit.ui.fitting import FitCancelled, patch_colors, percent
from meshfit.ui.fitview import FitLayers, grid_lines, legend_html
from meshfit.ui.state import Session

__all__ = ["App"]

_REGION_BAD = (225, 80, 70)
_HIGHLIGHT = (255, 235, 0)
#: click modes of the 3D view, as the dropdown lists them
MODES = ("boundary", "feature", "edit", "select", "brush", "view")
#: output formats the export panel offers, with their hints
FORMAT_HINTS = {
    "usd": "USD stage: watertight mesh with UVs, material reading the maps, NURBS patches",
    "3dm": "Rhino 3dm: the B-spline patches as NURBS surfaces",
    "iges": "IGES 5.3: the patches as rational B-spline surfaces (entity 128)",
    "step": "STEP AP214 through OpenCASCADE (pip install 'meshfit[cad]')",
    "obj": "OBJ mesh of the displaced surface with its material",
    "glb": "glTF binary of the displaced surface",
    "ply": "PLY mesh of the displaced surface",
    "exr": "the displacement maps as float32 OpenEXR (UDIM tiles)",
    "png": "the displacement maps as 16-bit PNG (UDIM tiles)",
}
_BOUNDARY = (20, 20, 230)
_FEATURE = (230, 120, 20)
_CREASE = (170, 20, 60)
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
        # plain lights, no image-based environment and no shadow maps: a browser without a
        # GPU (software WebGL) spends seconds a frame on those, and first paint waits for them
        self.server.scene.configure_environment_map(hdri=None)
        self.server.scene.configure_default_lights(cast_shadow=False)
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
        #: the patch selected by a click (highlighted, its figures shown), or None
        self.selected_patch: int | None = None
        self.layers = None if session.mesh is None else FitLayers(self.server.scene, session.mesh)
        self._cancel = threading.Event()
        self._fit_thread: threading.Thread | None = None
        self._stages: dict[str, tuple[int, int]] = {}
        self._quiet = False
        self._build_gui(layout_path)
        self._add_shortcuts()
        self.server.scene.on_click()(self._on_click)
        self.server.on_client_connect(self._frame_camera)
        self.redraw(mesh=True)
        if session.mesh is not None:
            self.say(_opened(session.mesh))

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
                "Click mode",
                MODES,
                initial_value="boundary",
                hint="What a click on the model does: paint a boundary or feature curve (B, F), "
                "pick and pull a curve (E), select a patch or curve (S), paint on the selected "
                "patch's map (M), or nothing (V)",
            )
            gui.add_button(
                "Finish curve", hint="End the curve at its last pick (it is then selected)"
            ).on_click(lambda _: self._on_finish())
            gui.add_button("Cancel curve", hint="Drop the curve being painted").on_click(
                lambda _: self._run(s.cancel_curve) is not FAILED and self.say("curve cancelled")
            )
            gui.add_button("Undo", hint="Undo the last edit (Ctrl+Z)").on_click(
                lambda _: self._on_undo()
            )
            gui.add_button("Redo", hint="Redo the last undone edit (Ctrl+Y)").on_click(
                lambda _: self._on_redo()
            )
            self.gui_curve = gui.add_number(
                "Selected curve",
                initial_value=-1,
                step=1,
                hint="The curve the edit buttons act on (-1: none); a click in select or "
                "edit mode sets it",
            )
            self.gui_curve.on_update(lambda _: self._select(int(self.gui_curve.value)))
            gui.add_button("Delete curve", hint="Remove the selected curve").on_click(
                lambda _: self._on_delete()
            )

        with gui.add_folder("Edit", expand_by_default=False):
            self.gui_section = gui.add_slider(
                "Edit section",
                min=2,
                max=60,
                step=1,
                initial_value=8,
                hint="Samples either side of the edit point that move with it",
            )
            self.gui_fair = gui.add_slider(
                "Fairness",
                min=0.0,
                max=4.0,
                step=0.1,
                initial_value=1.0,
                hint="Weight of the snake's evenness (larger: smoother, shorter curves)",
            )
            self.gui_curv = gui.add_slider(
                "Curvature",
                min=0.0,
                max=4.0,
                step=0.1,
                initial_value=0.0,
                hint="Weight of the snake's bending term",
            )
            self.gui_iters = gui.add_slider(
                "Iterations",
                min=1,
                max=2000,
                step=1,
                initial_value=200,
                hint="Most relaxation steps of Smooth curve",
            )
            gui.add_button(
                "Smooth curve", hint="Relax the selected curve as a surface snake, ends fixed"
            ).on_click(lambda _: self._on_curve_action("smooth"))
            gui.add_button("Snake step", hint="One relaxation step of the selected curve").on_click(
                lambda _: self._on_curve_action("step")
            )
            self.gui_ncontrol = gui.add_slider(
                "Control vertices",
                min=4,
                max=30,
                step=1,
                initial_value=8,
                hint="Control vertices of the space curve fitted for dragging",
            )
            gui.add_button(
                "Fit space curve",
                hint="Fit a B-spline space curve to the selected curve; drag its control "
                "vertices to reshape it",
            ).on_click(lambda _: self._on_curve_action("space"))
            self.gui_color = gui.add_checkbox(
                "Colour attraction",
                initial_value=False,
                hint="Pull curves toward features of the scan's colours or curvature",
            )
            self.gui_color_weight = gui.add_slider(
                "Colour weight",
                min=0.0,
                max=5.0,
                step=0.1,
                initial_value=1.0,
                hint="Strength of the colour attraction against the snake's own forces",
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
                hint="The field colour attraction follows",
            )
            self.gui_sign = gui.add_dropdown(
                "Attract to",
                ("high", "low"),
                initial_value="high",
                hint="Up the field (bright bands, ridges) or down it",
            )
            for h in (self.gui_color, self.gui_color_weight, self.gui_field, self.gui_sign):
                h.on_update(lambda _: self._on_color())

        with gui.add_folder("Layout"):
            gui.add_button(
                "Check layout", hint="Which regions are four-sided patches, and the problems"
            ).on_click(lambda _: self._show_status())
            gui.add_button(
                "Automatic layout",
                hint="Replace the curves by an automatic layout (creases become C0 boundaries)",
            ).on_click(lambda _: self._run(s.auto_layout) is not FAILED and self._show_status())
            self.gui_regions = gui.add_checkbox(
                "Colour regions",
                initial_value=False,
                hint="Colour each region of the painted network; regions that are no patch "
                "are red with a badge saying why",
            )
            self.gui_regions.on_update(lambda _: self.redraw(mesh=True))
            self.gui_status = gui.add_markdown("")

        with gui.add_folder("Fit"):
            self.gui_default_cont = gui.add_dropdown(
                "Default continuity",
                ("G1", "C0"),
                initial_value=s.default_continuity,
                hint="Continuity across boundaries without a choice of their own (G1: "
                "tangent planes match; C0: positions only)",
            )
            self.gui_default_cont.on_update(lambda _: self._on_default_continuity())
            self.gui_curve_cont = gui.add_dropdown(
                "Curve continuity",
                ("default", "C0", "G1"),
                initial_value="default",
                hint="Continuity across the selected boundary curve (creases of the automatic "
                "layout start at C0)",
            )
            self.gui_curve_cont.on_update(lambda _: self._on_curve_continuity())
            self.gui_fcu = gui.add_slider(
                "Fit controls u",
                min=4,
                max=40,
                step=1,
                initial_value=16,
                hint="Control points per patch along u",
            )
            self.gui_fcv = gui.add_slider(
                "Fit controls v",
                min=4,
                max=40,
                step=1,
                initial_value=16,
                hint="Control points per patch along v",
            )
            self.gui_map_kind = gui.add_dropdown(
                "Map kind",
                ("vector", "scalar"),
                initial_value="vector",
                hint="Vector maps hold the exact detail; scalar maps a height along the normal",
            )
            gui.add_button(
                "Fit model", hint="Fit every patch (spring meshes, splines, maps, stitching)"
            ).on_click(lambda _: self._on_fit_model())
            gui.add_button("Cancel fit", hint="Stop the running fit").on_click(
                lambda _: self._on_cancel()
            )
            self.gui_fit_progress = gui.add_progress_bar(0.0, visible=False)
            self.gui_fit_stages = gui.add_markdown("")
            # a bar per stage of the fit, in the pipeline's order, shown while a fit runs
            from meshfit.pipeline.stages import STAGES

            with gui.add_folder("Fit stages", visible=False) as self.gui_stage_folder:
                self.gui_stage_bars = {}
                for name in STAGES:
                    gui.add_markdown(f"<sub>{name}</sub>")
                    self.gui_stage_bars[name] = gui.add_progress_bar(0.0)
            gui.add_button(
                "Re-fit selected patch",
                hint="Fit the selected patch again at the controls above (its neighbours "
                "are not touched)",
            ).on_click(lambda _: self._on_refit_patch())
            gui.add_button(
                "Re-fit all patches",
                hint="Fit every patch again at the controls above from its spring mesh "
                "(a preview; Fit model stitches the seams)",
            ).on_click(lambda _: self._on_refit_all())
            self.gui_patch_info = gui.add_markdown("")

        with gui.add_folder("View"):
            self.gui_show_scan = gui.add_checkbox(
                "Scan", initial_value=True, hint="Show the scanned mesh"
            )
            self.gui_show_layout = gui.add_checkbox(
                "Layout", initial_value=True, hint="Show the boundary and feature curves"
            )
            self.gui_show = {
                "springs": gui.add_checkbox(
                    "Spring grids", initial_value=False, hint="Show each patch's spring mesh"
                ),
                "spline": gui.add_checkbox(
                    "Spline", initial_value=False, hint="Show the fitted B-spline surfaces"
                ),
                "displaced": gui.add_checkbox(
                    "Displaced",
                    initial_value=True,
                    hint="Show the splines with their displacement maps applied",
                ),
            }
            self.gui_deviation = gui.add_checkbox(
                "Deviation colours",
                initial_value=True,
                hint="Colour the fitted surfaces by their distance to the scan (else one "
                "colour per patch)",
            )
            self.gui_labels = gui.add_checkbox(
                "Patch numbers", initial_value=True, hint="Show each patch's number"
            )
            self.gui_legend = gui.add_html("")
            self.gui_show_scan.on_update(lambda _: self._on_view())
            self.gui_show_layout.on_update(lambda _: self._on_view())
            for h in (*self.gui_show.values(), self.gui_labels):
                h.on_update(lambda _: self._on_view())
            self.gui_deviation.on_update(lambda _: self._on_deviation())

        with gui.add_folder("Map brush", expand_by_default=False):
            self.gui_brush_radius = gui.add_slider(
                "Brush radius %",
                min=0.2,
                max=20.0,
                step=0.1,
                initial_value=3.0,
                hint="Radius of the brush, percent of the bounding-box diagonal",
            )
            self.gui_brush_amount = gui.add_slider(
                "Brush height %",
                min=0.01,
                max=5.0,
                step=0.01,
                initial_value=0.5,
                hint="Height added at the brush centre, percent of the diagonal",
            )
            self.gui_brush_dir = gui.add_dropdown(
                "Brush",
                ("raise", "lower"),
                initial_value="raise",
                hint="Add to the map (raise the surface) or take away (lower it)",
            )

        with gui.add_folder("Preview"):
            self.gui_patch = gui.add_number(
                "Patch",
                initial_value=0,
                min=0,
                step=1,
                hint="The patch the spring and spline previews show (a selected patch sets it)",
            )
            self.gui_level = gui.add_slider(
                "Spring level",
                min=0,
                max=4,
                step=1,
                initial_value=0,
                hint="Spring-mesh level to preview (each level doubles the grid)",
            )
            gui.add_button(
                "Spring mesh", hint="Show the patch's spring mesh at the level"
            ).on_click(lambda _: self._on_springs())
            gui.add_button(
                "Run levels", hint="Show the levels from 0 up to the chosen one, coarse to fine"
            ).on_click(lambda _: self._on_run_levels())
            gui.add_button("Pause / continue", hint="Pause or continue Run levels").on_click(
                lambda _: self._on_pause()
            )
            self.gui_cu = gui.add_slider(
                "Controls u",
                min=4,
                max=40,
                step=1,
                initial_value=8,
                hint="Preview spline controls along u (re-fits as it moves)",
            )
            self.gui_cv = gui.add_slider(
                "Controls v",
                min=4,
                max=40,
                step=1,
                initial_value=8,
                hint="Preview spline controls along v (re-fits as it moves)",
            )
            self.gui_cu.on_update(lambda _: self._on_fit())
            self.gui_cv.on_update(lambda _: self._on_fit())
            gui.add_button(
                "Fit B-spline", hint="Fit a spline to the previewed spring mesh"
            ).on_click(lambda _: self._on_fit())
            self.gui_fitinfo = gui.add_markdown("")
            self.gui_image = gui.add_image(np.zeros((8, 8, 3), np.uint8), label="Displacement")

        with gui.add_folder("Files"):
            default = "" if layout_path is None else str(layout_path)
            self.gui_layout_path = gui.add_text(
                "Layout file",
                initial_value=default or "layout.json",
                hint="Layout JSON in the working folder (or the one named on the command line)",
            )
            gui.add_button("Save layout", hint="Write the layout file").on_click(
                lambda _: self._on_save()
            )
            gui.add_button("Load layout", hint="Read the layout file and edit its curves").on_click(
                lambda _: self._on_load()
            )
            self.gui_export = gui.add_text(
                "Export folder",
                initial_value="export",
                hint="Folder inside the working folder the exports go to",
            )
            from meshfit.export import step_available
            from meshfit.export.units import UNITS

            self.gui_formats = {}
            for name, hint in FORMAT_HINTS.items():
                missing = name == "step" and not step_available()
                self.gui_formats[name] = gui.add_checkbox(
                    name.upper() + (" (not installed)" if missing else ""),
                    initial_value=name in ("usd", "obj", "exr"),
                    disabled=missing,
                    hint=hint,
                )
            self.gui_units = gui.add_dropdown(
                "Units",
                tuple(UNITS),
                initial_value="mm",
                hint="The length unit of the scan's coordinates, declared by every export "
                "(never scaled)",
            )
            self.gui_up = gui.add_dropdown(
                "Up axis",
                ("auto", "y", "z"),
                initial_value="auto",
                hint="The axis the exports declare as up (never turned)",
            )
            gui.add_button(
                "Export",
                hint="Write the chosen formats (the last fit; without one, fit first)",
            ).on_click(lambda _: self._on_export())
            self.gui_progress = gui.add_progress_bar(0.0, visible=False)
            self.gui_upload = gui.add_upload_button(
                "Open mesh", mime_type="*/*", hint="Open a mesh file (PLY, OBJ, STL, OFF, GLB)"
            )
            self.gui_upload.on_upload(lambda _: self._on_upload())

    def _add_shortcuts(self) -> None:
        """Keyboard shortcuts (viser's command palette hotkeys) for modes, undo and redo."""
        gui = self.server.gui
        for label, key, mode in (
            ("Paint boundary curves", "B", "boundary"),
            ("Paint feature curves", "F", "feature"),
            ("Edit curves", "E", "edit"),
            ("Select patches and curves", "S", "select"),
            ("Paint on the map", "M", "brush"),
            ("View only", "V", "view"),
        ):
            gui.add_command(label, hotkey=key).on_trigger(lambda _, m=mode: self._set_mode(m))
        gui.add_command("Undo", hotkey="Z", modifier="cmd/ctrl").on_trigger(
            lambda _: self._on_undo()
        )
        gui.add_command("Redo", hotkey="Y", modifier="cmd/ctrl").on_trigger(
            lambda _: self._on_redo()
        )
        gui.add_command("Redo (Ctrl+Shift+Z)", hotkey="Z", modifier="cmd/ctrl+shift").on_trigger(
            lambda _: self._on_redo()
        )

    def _set_mode(self, mode: str) -> None:
        self.gui_mode.value = mode
        self.say(f"click mode: {mode}")

    def _on_undo(self) -> None:
        self.say("undone" if self._run(self.session.undo) is True else "nothing to undo")

    def _on_redo(self) -> None:
        self.say("redone" if self._run(self.session.redo) is True else "nothing to redo")

    def _on_finish(self) -> None:
        i = self._run(self.session.finish_curve)
        if i is not FAILED:
            self._select(int(i))
            self.say(f"curve {i} finished and selected")

    # ------------------------------------------------------------------------ drawing
    def _lift(self, xyz: np.ndarray, faces: np.ndarray) -> np.ndarray:
        """Lift points off the surface along their face normal so curves stay visible."""
        mesh = self.session.mesh
        return xyz + mesh.face_normals[faces] * (0.002 * mesh.bbox_diagonal)

    def redraw(self, *, mesh: bool = False) -> None:
        """Draw the scan (with ``mesh``) and the curves again (one redraw at a time)."""
        with self.lock:
            self._redraw(mesh)

    def _redraw(self, mesh: bool) -> None:
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
            if i == self.selected:
                col = _SELECTED
            elif pc.ends is None:
                col = _FEATURE
            else:
                col = _CREASE if (pc.continuity or s.default_continuity) == "C0" else _BOUNDARY
            self._keep(
                "/curves",
                scene.add_line_segments(
                    f"/curves/c{i}",
                    np.stack([x[:-1], x[1:]], axis=1),
                    col,
                    thickness=width,
                    visible=bool(self.gui_show_layout.value),
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
            # every pick as a dot: the first click of a curve shows before there is a line
            x = self._lift(m.xyz(st.picks), st.picks.face)
            self._keep(
                "/curves",
                scene.add_point_cloud(
                    "/curves/picks",
                    x,
                    np.tile(np.asarray(_STROKE, np.uint8), (len(x), 1)),
                    point_size=0.01 * m.bbox_diagonal,
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
                    visible=bool(self.gui_show_layout.value),
                ),
            )
        self._draw_gizmos()
        self.gui_curve.value = -1 if self.selected is None else self.selected
        if self.selected is not None and self.selected < len(s.curves):
            self.gui_curve_cont.value = s.curves[self.selected].continuity or "default"

    def _clear(self, prefix: str) -> None:
        for h in self._nodes.pop(prefix, []):
            h.remove()

    def _keep(self, prefix: str, handle) -> None:
        self._nodes.setdefault(prefix, []).append(handle)

    def _draw_mesh(self, m: Mesh) -> None:
        scene = self.server.scene
        self._clear("/mesh")
        self._clear("/badges")
        if self.gui_regions.value and self.session.curves:
            st = self.session.status()
            if st.regions:
                rof = st.region_of_face
                palette = patch_colors(len(st.regions))
                k = 0  # patch number of the next valid region
                for r in st.regions:
                    f = m.faces[rof == r.index]
                    col = palette[k] if r.valid else np.asarray(_REGION_BAD)
                    k += int(r.valid)
                    if f.size:
                        self._keep(
                            "/mesh",
                            scene.add_mesh_simple(
                                f"/mesh/region{r.index}",
                                m.vertices,
                                f,
                                color=tuple(int(c) for c in col),
                                visible=bool(self.gui_show_scan.value),
                            ),
                        )
                    if not r.valid and f.size:  # a badge saying why it is no patch
                        centre = m.vertices[f].mean(axis=(0, 1))
                        at = m.xyz(m.closest_points(centre[None]).points)[0]
                        self._keep(
                            "/badges",
                            scene.add_label(
                                f"/badges/region{r.index}",
                                f"region {r.index}: no patch",
                                position=tuple(at),
                                anchor="center-center",
                            ),
                        )
                return
        if m.vertex_colors is not None:
            import trimesh

            tm = trimesh.Trimesh(
                m.vertices, m.faces, vertex_colors=m.vertex_colors[:, :3], process=False
            )
            self._keep(
                "/mesh",
                scene.add_mesh_trimesh("/mesh/surface", tm, visible=bool(self.gui_show_scan.value)),
            )
        else:
            self._keep(
                "/mesh",
                scene.add_mesh_simple(
                    "/mesh/surface",
                    m.vertices,
                    m.faces,
                    color=(200, 200, 200),
                    visible=bool(self.gui_show_scan.value),
                ),
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
            if what == "finished":  # the new curve is selected, ready for the edit buttons
                self.selected, self.edit_point = len(s.curves) - 1, None
                self.redraw()
            if what is not FAILED:
                done = f"; curve {self.selected} selected" if what == "finished" else ""
                self.say(
                    f"{mode} pick: {what} ({plural(len(s.curves), 'curve')}, "
                    f"{plural(len(s.corners), 'corner')}){done}"
                )
            return
        if mode == "select":
            self._on_select_click(o, d)
            return
        if mode == "brush":
            self._on_brush_click(o, d)
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
                pc = percent(move, s.mesh.bbox_diagonal)
                self.say(
                    f"curve {self.selected}: one snake step, largest move {pc:.3g} % of the "
                    "diagonal"
                )
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
            text = _status_text(st)
        self.gui_status.content = text
        self.say(text.splitlines()[0])
        if self.gui_regions.value:
            self.redraw(mesh=True)
        return True

    # ------------------------------------------------------------------------ previews
    def _show_grid(self, grid) -> None:
        x = np.asarray(grid.xyz)
        nu, nv = x.shape[:2]
        lines = grid_lines(x)
        self._clear("/preview/springs")
        self._keep(
            "/preview/springs",
            self.server.scene.add_line_segments(
                "/preview/springs",
                self._lift_points(lines.reshape(-1, 3)).reshape(-1, 2, 3),
                (30, 30, 120),
                thickness=1.5,
                thickness_units="screen",
            ),
        )
        shown = len(np.unique(lines[:, :, :].reshape(-1, 3), axis=0))
        thinned = "" if shown >= nu * nv else " (every few grid lines drawn)"
        self.say(f"patch {grid.patch}: spring mesh level {grid.level}, {nu} x {nv} points{thinned}")

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
        diag = s.mesh.bbox_diagonal
        self.gui_fitinfo.content = (
            f"patch {p}: {cp[0]} x {cp[1]} controls, RMS {percent(fit.rms, diag):.3g} %, max "
            f"{percent(float(fit.error.max()), diag):.3g} % of the diagonal"
        )
        self.say(self.gui_fitinfo.content)

    # ------------------------------------------------------------------------ the fit
    def _lift_points(self, xyz: np.ndarray) -> np.ndarray:
        """Points lifted off the scan along the normal of their closest face."""
        m = self.session.mesh
        f = m.closest_points(xyz).points.face
        return xyz + m.face_normals[f] * (0.002 * m.bbox_diagonal)

    def _fit_options(self):
        from meshfit.pipeline import FitOptions

        return FitOptions(
            controls=(int(self.gui_fcu.value), int(self.gui_fcv.value)),
            map_kind=str(self.gui_map_kind.value),
            units=str(self.gui_units.value),
            up_axis=str(self.gui_up.value),
        )

    def _on_fit_model(self) -> None:
        """Fit the whole model on a thread: a progress bar per stage, a cancel button."""
        if self._fit_thread is not None and self._fit_thread.is_alive():
            self.say("a fit is running: wait for it or cancel it")
            return
        opts = self._run(self._fit_options, redraw=False)
        if opts is FAILED:
            return
        self._cancel.clear()
        self._stages = {}
        self.gui_fit_progress.value = 0.0
        self.gui_fit_progress.visible = True
        for bar in self.gui_stage_bars.values():
            bar.value = 0.0
        self.gui_stage_folder.visible = True
        self.say("fitting the model...")

        def work() -> None:
            t0 = time.perf_counter()
            try:
                result = self.session.fit_model(
                    options=opts, progress=self._fit_progress, cancel=self._cancel
                )
            except FitCancelled as exc:
                self.gui_fit_stages.content = f"fit: {exc}"
                self.say(f"{exc}; the view keeps the last fit")
                return
            except MeshfitError as exc:
                self.say(f"**refused:** {exc}")
                return
            except Exception as exc:  # keep the server alive; show what broke
                traceback.print_exc()
                self.say(f"**error:** {type(exc).__name__}: {exc}")
                return
            finally:
                self.gui_fit_progress.visible = False
                self.gui_stage_folder.visible = False
            with self.lock:
                first = self.layers is None or not self.layers.nodes
                self._draw_fit(result)
                if first:  # the fit over the scan: the spline's deviation, the scan hidden
                    self._quiet = True
                    try:
                        self.gui_show_scan.value = False
                        self.gui_show["spline"].value = True
                        self.gui_show["displaced"].value = False
                    finally:
                        self._quiet = False
            e = result.errors
            diag_pc = "percent of the diagonal"
            spline = 100 * e["spline_only"]["hausdorff"]
            disp = e["displaced"]
            shown = "" if not disp else f", displaced {100 * disp['hausdorff']:.3g} %"
            self.say(
                f"fitted {plural(len(result.patches), 'patch')} in "
                f"{time.perf_counter() - t0:.1f} s: Hausdorff distance spline "
                f"{spline:.3g} %{shown} ({diag_pc})"
            )

        self._fit_thread = threading.Thread(target=work, daemon=True)
        self._fit_thread.start()

    def _fit_progress(self, stage: str, done: int, total: int) -> None:
        """A progress bar for the running stage, a bar per stage and a line per stage."""
        self._stages[stage] = (done, total)
        frac = done / total if total else 1.0
        self.gui_fit_progress.value = float(100.0 * min(max(frac, 0.0), 1.0))
        bar = self.gui_stage_bars.get(stage)
        if bar is not None:
            bar.value = self.gui_fit_progress.value
        rows = []
        for name, (d, n) in self._stages.items():
            mark = "done" if (n and d >= n) else f"{d}/{n}"
            rows.append(f"{name} {mark}")
        self.gui_fit_stages.content = "fit: " + " · ".join(rows)

    def _on_cancel(self) -> None:
        if self._fit_thread is None or not self._fit_thread.is_alive():
            self.say("no fit is running")
            return
        self._cancel.set()
        self.say("cancelling the fit...")

    def _draw_fit(self, result) -> None:
        if self.layers is None or self.layers.mesh is not self.session.mesh:
            if self.layers is not None:
                self.layers.clear()
            self.layers = FitLayers(self.server.scene, self.session.mesh)
        for name, box in self.gui_show.items():
            self.layers.visible[name] = bool(box.value)
        self.layers.deviation = bool(self.gui_deviation.value)
        self.layers.show_labels = bool(self.gui_labels.value)
        self.layers.draw(result)
        self.gui_legend.content = legend_html(self.layers.top, "Deviation from the scan")
        if self.selected_patch is not None and self.selected_patch < len(result.patches):
            self._show_patch_info(self.selected_patch)

    def _on_view(self) -> None:
        with self.lock:
            for h in self._nodes.get("/mesh", []):
                h.visible = bool(self.gui_show_scan.value)
            for h in self._nodes.get("/curves", []):
                h.visible = bool(self.gui_show_layout.value)
            if self.layers is not None:
                for name, box in self.gui_show.items():
                    self.layers.set_visible(name, bool(box.value))
                self.layers.set_labels(bool(self.gui_labels.value))
        if not self._quiet:
            shown = [n for n, b in self._view_boxes() if b]
            self.say("showing: " + (", ".join(shown) or "nothing"))

    def _show_only_displaced(self) -> None:
        self._quiet = True  # (the checkboxes' callbacks redraw; the brush says what it did)
        try:
            self.gui_show["displaced"].value = True
            self.gui_show["spline"].value = False
        finally:
            self._quiet = False

    def _view_boxes(self) -> list[tuple[str, bool]]:
        return [
            ("scan", bool(self.gui_show_scan.value)),
            ("layout", bool(self.gui_show_layout.value)),
            *((n, bool(b.value)) for n, b in self.gui_show.items()),
        ]

    def _on_deviation(self) -> None:
        result = self.session.result
        if result is None or self.layers is None:
            return
        with self.lock:
            self.layers.deviation = bool(self.gui_deviation.value)
            for p in range(len(result.patches)):
                self.layers.draw_patch(result, p, measure=False)
        self.say("colours: " + ("deviation from the scan" if self.layers.deviation else "patches"))

    def _controls(self) -> tuple[int, int]:
        return int(self.gui_fcu.value), int(self.gui_fcv.value)

    def _on_refit_patch(self) -> None:
        p = self.selected_patch
        if p is None:
            self.say("select a patch first (select mode: click it)")
            return
        result = self._run(self.session.refit_patch, p, controls=self._controls(), redraw=False)
        if result is FAILED:
            return
        with self.lock:
            self.layers.draw_patch(result, p)
        self._show_patch_info(p)
        mu, mv = result.patches[p].surface.control_points.shape[:2]
        self.say(f"patch {p} re-fitted with {mu} x {mv} controls")

    def _on_refit_all(self) -> None:
        t0 = time.perf_counter()
        result = self._run(self.session.refit_all, controls=self._controls(), redraw=False)
        if result is FAILED:
            return
        with self.lock:
            self._draw_fit(result)
        self.say(
            f"{plural(len(result.patches), 'patch')} re-fitted in "
            f"{time.perf_counter() - t0:.2f} s (seams are closed by Fit model)"
        )

    def _on_default_continuity(self) -> None:
        value = str(self.gui_default_cont.value)
        if self._run(self.session.set_default_continuity, value) is FAILED:
            return
        self.say(f"default continuity: {self.session.default_continuity} (used by the next fit)")

    def _on_curve_continuity(self) -> None:
        i = self.selected
        value = str(self.gui_curve_cont.value)
        if i is None or i >= len(self.session.curves):
            return
        pc = self.session.curves[i]
        if (pc.continuity or "default") == value:
            return
        if self._run(self.session.set_curve_continuity, i, value) is not FAILED:
            self.say(f"curve {i}: {self.session.curve_continuity(i)} (used by the next fit)")

    # ------------------------------------------------------------------------ selection
    def _patch_of_face(self, face: int) -> int | None:
        """The patch a face of the scan is in: the last fit's, else the painted layout's."""
        result = self.session.result
        if result is not None and result.face_patch is not None:
            k = int(result.face_patch[face])
            return k if k >= 0 else None
        st = self.session.status()
        if st.error or not st.regions:
            return None
        r = int(st.region_of_face[face])
        valid = [q.index for q in st.regions if q.valid]
        return valid.index(r) if r in valid else None

    def _patch_faces(self, patch: int) -> np.ndarray:
        result = self.session.result
        if result is not None and result.face_patch is not None:
            return np.flatnonzero(result.face_patch == patch)
        st = self.session.status()
        valid = [q for q in st.regions if q.valid]
        return np.flatnonzero(st.region_of_face == valid[patch].index)

    def _on_select_click(self, origin, direction) -> None:
        s = self.session
        with self.lock:
            hit = s.pick(origin, direction)
        if hit is None:
            self.say("select: the click missed the mesh")
            return
        near = s.nearest_sample(s.mesh.xyz(hit)[0])
        if near is not None:
            self._select(near[0])
            pc = s.curves[near[0]]
            cont = "" if pc.ends is None else s.curve_continuity(near[0])
            what = "feature curve" if pc.ends is None else f"boundary, {cont}"
            self.say(f"curve {near[0]} selected ({what})")
            return
        k = self._patch_of_face(int(hit.face[0]))
        if k is None:
            self.say("select: no patch there (check the layout)")
            return
        self.select_patch(k)

    def select_patch(self, k: int) -> None:
        """Highlight patch ``k``, frame every client's camera on it and show its figures."""
        with self.lock:
            faces = self._patch_faces(k)
            self.selected_patch = k
            self.gui_patch.value = k
            self._highlight(faces)
            self._frame_on(faces)
            self._show_patch_info(k)
        self.say(self.gui_patch_info.content.splitlines()[0].strip("*"))

    def _highlight(self, faces: np.ndarray) -> None:
        m = self.session.mesh
        self._clear("/select")
        tri = (
            m.vertices[m.faces[faces]]
            + (0.001 * m.bbox_diagonal) * m.face_normals[faces][:, None, :]
        )
        self._keep(
            "/select",
            self.server.scene.add_mesh_simple(
                "/select/patch",
                tri.reshape(-1, 3),
                np.arange(3 * len(faces), dtype=np.int64).reshape(-1, 3),
                color=_HIGHLIGHT,
                opacity=0.6,
            ),
        )

    def _frame_on(self, faces: np.ndarray) -> None:
        """Look at the faces from outside, along their mean normal."""
        m = self.session.mesh
        area = m.face_areas[faces]
        corner = m.vertices[m.faces[faces, 0]]  # a vertex per face: within an edge of it
        c = area @ corner / area.sum()
        n = area @ m.face_normals[faces]
        if np.linalg.norm(n) < 1e-12:
            n = c - 0.5 * (m.bbox[0] + m.bbox[1])
        n = n / (np.linalg.norm(n) or 1.0)
        lo, hi = corner.min(axis=0), corner.max(axis=0)
        dist = max(2.0 * float(np.linalg.norm(hi - lo)), 0.15 * m.bbox_diagonal)
        up = np.array([0.0, 1.0, 0.0]) if abs(n[1]) < 0.9 else np.array([0.0, 0.0, 1.0])
        for client in self.server.get_clients().values():
            client.camera.up_direction = tuple(up)
            client.camera.position = tuple(c + n * dist)
            client.camera.look_at = tuple(c)

    def _show_patch_info(self, k: int) -> None:
        s = self.session
        diag = s.mesh.bbox_diagonal
        result = s.result
        if result is not None and k < len(result.patches):
            pf = result.patches[k]
            f = self.layers.figures(result, k) if self.layers is not None else {}
            nu, nv = pf.spring.shape[:2]
            mu, mv = pf.surface.control_points.shape[:2]
            h, w = pf.displacement.shape
            rows = [
                f"**patch {k}: {mu} x {mv} controls**",
                f"- spring mesh {nu} x {nv}, {pf.displacement.kind} map {h} x {w}",
                f"- spline to scan: max {f['spline_max']:.3g} %, RMS {f['spline_rms']:.3g} %",
                f"- displaced to scan: max {f['displaced_max']:.3g} %, "
                f"RMS {f['displaced_rms']:.3g} %",
            ]
            far = pf.errors.get("input_distance_max")
            if far is not None:
                rows.append(f"- scan to displaced: max {100 * far:.3g} %")
            rows.append("(percent of the bounding-box diagonal)")
        else:
            faces = self._patch_faces(k)
            area = float(s.mesh.face_areas[faces].sum())
            rows = [
                f"**patch {k}: {len(faces)} faces (not fitted yet)**",
                f"- area {100 * area / diag**2:.3g} % of the diagonal squared",
            ]
        self.gui_patch_info.content = "\n".join(rows)

    def _on_brush_click(self, origin, direction) -> None:
        s = self.session
        if s.result is None:
            self.say("map brush: fit the model first")
            return
        with self.lock:
            hit = s.pick(origin, direction)
        if hit is None:
            self.say("map brush: the click missed the mesh")
            return
        k = self._patch_of_face(int(hit.face[0]))
        if k is None:
            return
        if k != self.selected_patch:
            self.select_patch(k)
        if not self.gui_show["displaced"].value:  # the brush moves the displaced surface
            self._show_only_displaced()
        diag = s.mesh.bbox_diagonal
        sign = 1.0 if self.gui_brush_dir.value == "raise" else -1.0
        amount = sign * float(self.gui_brush_amount.value) / 100.0 * diag
        result = self._run(
            s.brush_map,
            k,
            s.mesh.xyz(hit)[0],
            radius=float(self.gui_brush_radius.value) / 100.0 * diag,
            amount=amount,
            redraw=False,
        )
        if result is FAILED:
            return
        with self.lock:
            for p in range(len(result.patches)):  # the rebuild closes the seams around it
                self.layers.draw_patch(result, p)
            self._show_patch_info(k)
        self.say(
            f"patch {k}: map {self.gui_brush_dir.value}d by "
            f"{float(self.gui_brush_amount.value):.3g} % of the diagonal"
        )

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
        formats = tuple(name for name, box in self.gui_formats.items() if box.value)
        units, up = str(self.gui_units.value), str(self.gui_up.value)

        def export():
            folder = self.policy.check_folder(self.gui_export.value)
            if self.session.result is not None:
                return self.session.export_fit(folder, formats=formats, units=units, up_axis=up)
            return self.session.export(
                folder,
                controls=(int(self.gui_cu.value), int(self.gui_cv.value)),
                formats=formats,
                units=units,
                up_axis=up,
                progress=self._progress,
            )

        self.gui_progress.value = 0.0
        self.gui_progress.visible = True
        try:
            out = self._run(export, redraw=False)
        finally:
            self.gui_progress.visible = False
        if out is not FAILED:
            self.say(
                f"exported {len(out)} files ({', '.join(formats)}; {units}, up "
                f"{up}) to {self.gui_export.value}"
            )

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
            self._clear("/select")
            self.selected_patch = None
            if self.layers is not None:
                self.layers.clear()
            self.layers = FitLayers(self.server.scene, mesh)
            self.gui_legend.content = ""
            self.gui_patch_info.content = ""
            self.say(f"opened {mesh.name}: {mesh.n_vertices} vertices, {mesh.n_faces} faces")
            if self.session.set_aside is not None:
                moved, why = self.session.set_aside
                self.say(f"{why}: moved it to {moved.name} and started a new session")


def _opened(mesh: Mesh) -> str:
    return (
        f"{mesh.name}: {mesh.n_vertices:,} vertices, {mesh.n_faces:,} faces. Click on it to "
        "paint boundary curves (B), or run Automatic layout; then Fit model."
    )


def _status_text(st) -> str:
    """The layout status in a few lines: the counts, then only the regions with a problem."""
    n_ok = sum(r.valid for r in st.regions)
    head = f"**{n_ok} of {len(st.regions)} regions are four-sided patches**"
    problems = [r for r in st.regions if _region_text(r) != "patch"]
    if not problems:
        return head
    rows = [head, ""]
    rows += [f"- region {r.index}: " + _region_text(r) for r in problems[:8]]
    if len(problems) > 8:
        rows.append(f"- and {len(problems) - 8} more regions with a problem")
    return "\n".join(rows)


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
