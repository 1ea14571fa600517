"""The web app's controller: the session state and one method per user action, no viser.

:class:`Session` holds the mesh, the painted corners and curves, the stroke being painted,
undo and redo stacks and the autosave file. Every action calls the public meshfit API
(:func:`meshfit.curves.paint_curve`, :func:`~meshfit.curves.relax_snake`,
:func:`~meshfit.curves.edit_snake`, :func:`~meshfit.curves.fit_space_curve`,
:func:`~meshfit.curves.move_control_point`, :func:`~meshfit.curves.color_force`,
:func:`meshfit.layout.layout_from_curves`, :func:`~meshfit.layout.extract_patches`,
:func:`meshfit.springs.resample_patch`, :func:`meshfit.bspline.fit_bspline`,
:func:`meshfit.displacement.displacement_map`); the browser layer (:mod:`meshfit.ui.app`)
only turns events into these calls and draws the results.

The editable state is an immutable snapshot (:class:`SessionState`); an action builds a new
snapshot, pushes the old one on the undo stack and writes the autosave file, so a crash
loses nothing and every edit can be undone.
"""

from __future__ import annotations

import base64
import json
import os
import threading
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from meshfit import _atomic, tol
from meshfit._jsonio import read_json_file
from meshfit.curves import (
    SnakeOptions,
    SpaceCurve,
    color_force,
    edit_snake,
    fit_space_curve,
    move_control_point,
    paint_curve,
    relax_snake,
    scalar_field,
    vertex_gradients,
)
from meshfit.errors import InputError, LayoutError
from meshfit.mesh import Mesh
from meshfit.types import SurfaceCurve, SurfacePoints
from meshfit.ui.network import NetworkStatus, network_status
from meshfit.ui.picking import pick_point

__all__ = [
    "SESSION_VERSION",
    "ColorAttraction",
    "PaintedCurve",
    "PatchFit",
    "Session",
    "SessionState",
    "Stroke",
]

#: version of the autosave / session JSON format (key ``"meshfit_ui_session"``); 2 stores face
#: points as base64 arrays, 1 (still read) as decimal lists
SESSION_VERSION = 2
#: session file versions :meth:`Session.restore` reads
READ_VERSIONS = (1, 2)

Kind = Literal["boundary", "feature"]
#: continuity choices across a boundary curve
CONTINUITY = ("C0", "G1")


@dataclass(frozen=True, eq=False)
class PaintedCurve:
    """A finished curve of the session.

    Attributes
    ----------
    curve : SurfaceCurve
        Open face-point curve.
    ends : (int, int) or None
        Start and end corner of a boundary curve; None for a feature curve.
    space : SpaceCurve or None
        The B-spline space curve fitted to it for control-vertex editing, if any.
    continuity : {"C0", "G1"} or None
        The continuity chosen for this boundary; None follows the session's default.
    """

    curve: SurfaceCurve
    ends: tuple[int, int] | None = None
    space: SpaceCurve | None = None
    continuity: str | None = None

    @property
    def kind(self) -> str:
        return self.curve.kind


@dataclass(frozen=True, eq=False)
class Stroke:
    """A curve being painted: its picks so far and the painted pieces between them.

    Attributes
    ----------
    kind : {"boundary", "feature"}
    picks : SurfacePoints
        The picks after snapping, in order.
    start_corner : int or None
        Corner the stroke starts at (boundary strokes).
    pieces : tuple of SurfacePoints
        ``len(picks) - 1`` painted pieces, piece ``i`` from pick ``i`` to pick ``i + 1``.
    """

    kind: Kind
    picks: SurfacePoints
    start_corner: int | None
    pieces: tuple[SurfacePoints, ...] = ()

    def points(self) -> SurfacePoints:
        """The stroke's painted points so far (the first pick alone before a second)."""
        if not self.pieces:
            return self.picks
        return SurfacePoints.concatenate(
            [self.pieces[0]] + [p[1:] for p in self.pieces[1:] if len(p) > 1]
        )


def _no_points() -> SurfacePoints:
    return SurfacePoints(np.zeros(0, np.int64), np.zeros((0, 3)))


@dataclass(frozen=True, eq=False)
class SessionState:
    """One undoable snapshot of the editable state."""

    corners: SurfacePoints = field(default_factory=_no_points)
    curves: tuple[PaintedCurve, ...] = ()
    stroke: Stroke | None = None

    @property
    def boundary_ids(self) -> list[int]:
        return [i for i, c in enumerate(self.curves) if c.ends is not None]

    @property
    def feature_ids(self) -> list[int]:
        return [i for i, c in enumerate(self.curves) if c.ends is None]


@dataclass(frozen=True)
class ColorAttraction:
    """Colour (scalar-field) attraction settings of snake relaxation (thesis sec. 3.8.2).

    Attributes
    ----------
    enabled : bool
    weight : float
        Weight against the internal forces (see :func:`meshfit.curves.color_force`).
    field : str
        A :func:`meshfit.curves.scalar_field` kind ("luminance", "red", "gaussian_curvature"...).
    sign : {1, -1}
        +1 attracts up the field (bright bands, ridges), -1 down it.
    """

    enabled: bool = False
    weight: float = 1.0
    field: str = "luminance"
    sign: int = 1


@dataclass(frozen=True, eq=False)
class PatchFit:
    """Live fit preview of one patch.

    Attributes
    ----------
    patch : int
    grid_xyz : (nu, nv, 3) float64
        The spring mesh the spline is fitted to.
    surface : meshfit.bspline.BSplineSurface
    spline_xyz : (nu, nv, 3) float64
        The spline at the grid parameters.
    error : (nu, nv) float64
        ``|grid - spline|`` per grid point, model units (eq. 6.1).
    rms : float
        RMS of ``error``.
    """

    patch: int
    grid_xyz: NDArray[np.float64]
    surface: object
    spline_xyz: NDArray[np.float64]
    error: NDArray[np.float64]
    rms: float


def _sp_to_json(sp: SurfacePoints) -> dict:
    """Face points as JSON values: the arrays' little-endian bytes in base64 (``face`` int64,
    ``bary`` float64 row by row): exact, and far faster to write than decimal lists."""
    return {
        "n": len(sp),
        "face": base64.b64encode(sp.face.astype("<i8", copy=False).tobytes()).decode("ascii"),
        "bary": base64.b64encode(sp.bary.astype("<f8", copy=False).tobytes()).decode("ascii"),
    }


def _b64_array(text: str, dtype: str) -> NDArray:
    raw = base64.b64decode(text.encode("ascii"), validate=True)
    if len(raw) % np.dtype(dtype).itemsize:
        raise ValueError(f"{len(raw)} bytes is no whole number of {dtype} values")
    return np.frombuffer(raw, dtype=dtype)


def _sp_from_json(d: dict, where: str) -> SurfacePoints:
    """Face points from a session file: base64 arrays (version 2) or decimal lists (1)."""
    try:
        f, b = d["face"], d["bary"]
        if isinstance(f, str) and isinstance(b, str):
            face = _b64_array(f, "<i8").astype(np.int64)
            bary = _b64_array(b, "<f8").astype(np.float64)
            if "n" in d and int(d["n"]) != face.size:
                raise ValueError(f"{face.size} faces where the file says {int(d['n'])}")
            if bary.size != 3 * face.size:
                raise ValueError(f"{bary.size} barycentric values for {face.size} faces")
            bary = bary.reshape(-1, 3)
        else:
            face = np.asarray(f, dtype=np.int64).reshape(-1)
            bary = np.asarray(b, float)
            if bary.size == 0:  # JSON keeps no shape for an empty list
                bary = bary.reshape(0, 3)
        return SurfacePoints(face, bary)
    except (KeyError, TypeError, ValueError, UnicodeEncodeError) as exc:
        raise InputError(f"{where}: bad face points ({exc})") from None


class Session:
    """The app's state and actions; every public method is one user action.

    Parameters
    ----------
    mesh : Mesh, optional
        The mesh to paint on (can be set later with :meth:`set_mesh`).
    autosave : path, optional
        File rewritten (atomically) after every change; None turns autosave off.
    spacing : float, optional
        Sample spacing of painted curves, model units; default half the mean edge length.
    max_history : int
        Undo steps kept.
    background_save : bool
        Write the autosave file on a background thread (default True): an action returns
        without waiting for the disk, the writer always writes the newest state, and
        :meth:`flush` waits for it. False writes inside every action.

    References
    ----------
    .. [1] Krishnamurthy, "Fitting Smooth Surfaces to Dense Polygon Meshes", PhD thesis,
       Stanford 2000, sec. 1.2.1 (interactive, with feedback at every stage), sec. 3.2
       (painting), sec. 3.3 (space-curve editing), sec. 3.8 (snake editing, colour
       attraction), sec. 5.7 and 5.13 (spring-mesh previews, coarse to fine).
    """

    def __init__(
        self,
        mesh: Mesh | None = None,
        *,
        autosave: str | os.PathLike | None = None,
        spacing: float | None = None,
        max_history: int = 200,
        background_save: bool = True,
    ) -> None:
        self.mesh: Mesh | None = None
        self.autosave_path = None if autosave is None else Path(autosave)
        #: (where a session file that could not be resumed was moved, why), or None
        self.set_aside: tuple[Path, str] | None = None
        self.spacing = spacing
        self.max_history = int(max_history)
        self.color = ColorAttraction()
        self.state = SessionState()
        self.undo_stack: list[SessionState] = []
        self.redo_stack: list[SessionState] = []
        self._cache: dict = {}
        self._fingerprint = ""
        self._json_parts: dict[int, tuple[object, str]] = {}
        self._json_lock = threading.Lock()
        self.background_save = bool(background_save)
        self._save_cv = threading.Condition()
        self._pending: tuple | None = None
        self._writing = False
        self._writer: threading.Thread | None = None
        self.save_errors: list[str] = []
        self.listeners: list[Callable[[], None]] = []
        #: continuity of the boundaries with no choice of their own ("C0" or "G1")
        self.default_continuity = "G1"
        #: the last whole fit (:meth:`fit_model`), with the previews' and brushes' edits
        self.result = None
        if mesh is not None:
            self.set_mesh(mesh)

    # ------------------------------------------------------------------------ bookkeeping
    def _need_mesh(self) -> Mesh:
        if self.mesh is None:
            raise InputError("no mesh is open: open one from a file or an upload first")
        return self.mesh

    def _commit(self, new: SessionState) -> SessionState:
        self.undo_stack.append(self.state)
        del self.undo_stack[: -self.max_history]
        self.redo_stack.clear()
        self._set(new)
        return new

    def _set(self, new: SessionState) -> None:
        self.state = new
        self._cache.clear()
        self._schedule_save()
        for f in list(self.listeners):
            f()

    def _schedule_save(self) -> None:
        if self.autosave_path is None or self.mesh is None:
            return
        job = (self.autosave_path, self.state, self.mesh, self._fingerprint)
        if not self.background_save:
            self._write(job)
            return
        with self._save_cv:
            self._pending = job
            if self._writer is None or not self._writer.is_alive():
                self._writer = threading.Thread(
                    target=self._write_loop, name="meshfit-autosave", daemon=True
                )
                self._writer.start()
            self._save_cv.notify_all()

    def _write(self, job: tuple) -> Path:
        path, state, mesh, fp = job
        return _atomic.write_text(path, self._json_of(state, mesh, fp))

    def _write_loop(self) -> None:
        while True:
            with self._save_cv:
                while self._pending is None:
                    if not self._save_cv.wait(timeout=60.0):
                        self._writer = None  # idle: end; the next change starts a new one
                        return
                job, self._pending = self._pending, None
                self._writing = True
            try:
                self._write(job)
            except OSError as exc:  # keep editing; report the failed write
                self.save_errors.append(f"autosave to {job[0]} failed: {exc}")
            finally:
                with self._save_cv:
                    self._writing = False
                    self._save_cv.notify_all()

    def resume_autosave(self, path: str | os.PathLike) -> bool:
        """Autosave to ``path`` from now on, first restoring it when it holds a session of the
        open mesh (the state a crash left); returns whether it was restored.

        A file there that is no valid session of this mesh (damaged, hand-edited, another
        mesh's) is never overwritten: it is renamed beside itself
        (``<name>.unreadable-<n>.json``, the first free n) and the session starts fresh;
        ``set_aside`` then holds ``(new path, reason)`` for the message to the user.
        """
        path = Path(path)
        self.flush()
        self.autosave_path = None
        self.set_aside = None
        restored = False
        if path.exists():
            try:
                self.restore(path)
                restored = True
            except InputError as exc:
                self.set_aside = (_move_aside(path), str(exc))
        self.autosave_path = path
        return restored

    def flush(self, timeout: float = 30.0) -> bool:
        """Wait until the autosave file holds the current state; False on timeout."""
        with self._save_cv:
            return self._save_cv.wait_for(
                lambda: self._pending is None and not self._writing, timeout=timeout
            )

    def autosave(self) -> Path | None:
        """Write the session file now, synchronously; returns its path (None when off)."""
        if self.autosave_path is None or self.mesh is None:
            return None
        self.flush()
        return self._write((self.autosave_path, self.state, self.mesh, self._fingerprint))

    @property
    def can_undo(self) -> bool:
        return bool(self.undo_stack)

    @property
    def can_redo(self) -> bool:
        return bool(self.redo_stack)

    def undo(self) -> bool:
        """Step back one edit; False when there is nothing to undo."""
        if not self.undo_stack:
            return False
        self.redo_stack.append(self.state)
        self._set(self.undo_stack.pop())
        return True

    def redo(self) -> bool:
        """Redo the last undone edit; False when there is nothing to redo."""
        if not self.redo_stack:
            return False
        self.undo_stack.append(self.state)
        self._set(self.redo_stack.pop())
        return True

    # ------------------------------------------------------------------------ mesh
    def set_mesh(self, mesh: Mesh) -> None:
        """Open a mesh: clears curves, history and previews."""
        if not isinstance(mesh, Mesh):
            raise InputError(f"expected a Mesh, got {type(mesh).__name__}")
        from meshfit.layout import mesh_fingerprint

        self.mesh = mesh
        self.result = None
        self._fingerprint = mesh_fingerprint(mesh)  # hashed once: autosave runs every edit
        with self._json_lock:
            self._json_parts.clear()
        self.undo_stack.clear()
        self.redo_stack.clear()
        self.color = replace(self.color, enabled=False)
        self._set(SessionState())

    @property
    def curves(self) -> tuple[PaintedCurve, ...]:
        return self.state.curves

    @property
    def corners(self) -> SurfacePoints:
        return self.state.corners

    def _spacing(self) -> float:
        mesh = self._need_mesh()
        return 0.5 * mesh.mean_edge_length if self.spacing is None else float(self.spacing)

    # ------------------------------------------------------------------------ painting
    def pick(self, origin: ArrayLike, direction: ArrayLike) -> SurfacePoints | None:
        """Face point under a click ray, or None (no state change)."""
        return pick_point(self._need_mesh(), origin, direction)

    def click(self, origin: ArrayLike, direction: ArrayLike, *, kind: Kind = "boundary") -> str:
        """Paint: cast the click ray and add the hit as the next pick of a ``kind`` curve.

        Returns
        -------
        str
            What happened ("missed", "started", "added", "finished"), for the status line.
        """
        hit = self.pick(origin, direction)
        if hit is None:
            return "missed"
        return self.add_pick(hit, kind=kind)

    def _snap_radius(self) -> float:
        return tol.length(self._need_mesh(), tol.UI_SNAP_RADIUS, scale="bbox_diagonal")

    def _nearest_corner(self, xyz: NDArray) -> tuple[int, float]:
        corners = self.state.corners
        if len(corners) == 0:
            return -1, np.inf
        d = np.linalg.norm(self._need_mesh().xyz(corners) - xyz, axis=1)
        k = int(np.argmin(d))
        return k, float(d[k])

    def _nearest_sample(
        self, xyz: NDArray, ids: list[int], *, interior: bool = False
    ) -> tuple[int, int, float]:
        mesh = self._need_mesh()
        best = (-1, -1, np.inf)
        for i in ids:
            c = self.state.curves[i].curve
            d = np.linalg.norm(mesh.xyz(c.points) - xyz, axis=1)
            if interior:
                if len(d) < 3:
                    continue
                d = d.copy()
                d[[0, -1]] = np.inf
            k = int(np.argmin(d))
            if d[k] < best[2]:
                best = (i, k, float(d[k]))
        return best

    def _snap_boundary(self, state: SessionState, pt: SurfacePoints) -> tuple[SessionState, int]:
        """The corner a boundary pick lands on: an existing corner, a new corner splitting a
        curve it lands on, or a new corner."""
        mesh = self._need_mesh()
        xyz = mesh.xyz(pt)[0]
        r = self._snap_radius()
        k, d = self._nearest_corner(xyz)
        if d <= r:
            return state, k
        i, s, d = self._nearest_sample(xyz, state.boundary_ids, interior=True)
        corners = SurfacePoints.concatenate([state.corners, pt])
        new = len(corners) - 1
        if d <= r:  # land on curve i: split it there; the sample becomes the corner
            pc = state.curves[i]
            pts = pc.curve.points
            corners = SurfacePoints.concatenate([state.corners, pts[s]])
            a, b = pc.ends
            first = PaintedCurve(
                SurfaceCurve(pts[: s + 1], kind="boundary"), (a, new), None, pc.continuity
            )
            second = PaintedCurve(
                SurfaceCurve(pts[s:], kind="boundary"), (new, b), None, pc.continuity
            )
            curves = list(state.curves)
            curves[i] = first
            curves.append(second)
            return replace(state, corners=corners, curves=tuple(curves)), new
        return replace(state, corners=corners), new

    def add_pick(self, point: SurfacePoints, *, kind: Kind = "boundary", end: bool = False) -> str:
        """Add a picked face point to the stroke being painted (starting one if needed).

        A boundary stroke starts at a corner: the pick snaps to an existing corner within
        ``tol.UI_SNAP_RADIUS`` of the bounding-box diagonal, or splits a boundary curve it
        lands on (the sample becomes a new corner), or makes a new corner. Each further pick
        paints the piece from the previous pick with :func:`meshfit.curves.paint_curve`; a
        pick that snaps to another corner ends the stroke there. With ``end=True`` the pick
        ends the stroke (snapping to a corner or splitting a curve it lands on, else a new
        corner). A feature stroke's ends snap to the nearest boundary-curve sample and end
        the stroke there.

        Returns
        -------
        str
            "started", "added" or "finished".
        """
        new, what = self._add(self.state, point, kind, end)
        self._commit(new)
        return what

    def _add(
        self, state: SessionState, point: SurfacePoints, kind: Kind, end: bool
    ) -> tuple[SessionState, str]:
        mesh = self._need_mesh()
        if kind not in ("boundary", "feature"):
            raise InputError(f"kind must be 'boundary' or 'feature', got {kind!r}")
        pt = SurfacePoints(point.face, point.bary)[0]
        stroke = state.stroke
        if stroke is not None and stroke.kind != kind:
            raise InputError(
                f"a {stroke.kind} curve is being painted: finish or cancel it before painting "
                f"a {kind} curve"
            )
        xyz = mesh.xyz(pt)[0]
        r = self._snap_radius()
        snapped_end = False
        end_corner = None
        if kind == "boundary":
            if stroke is None:
                state, c = self._snap_boundary(state, pt)
                return replace(state, stroke=Stroke(kind, state.corners[c], c)), "started"
            k, d = self._nearest_corner(xyz)
            if d <= r and k == stroke.start_corner and (end or len(stroke.picks) > 1):
                raise InputError(
                    "a boundary curve cannot end at the corner it starts from: finish it at "
                    "another corner (a loop takes at least two curves)"
                )
            if (d <= r and k != stroke.start_corner) or end:
                state, end_corner = self._snap_boundary(state, pt)
                pt = state.corners[end_corner]
                snapped_end = True
        else:
            i, s, d = self._nearest_sample(xyz, state.boundary_ids)
            if d <= r:
                pt = state.curves[i].curve.points[s]
                snapped_end = stroke is not None
            if stroke is None:
                return replace(state, stroke=Stroke(kind, pt, None)), "started"
            snapped_end = snapped_end or end
        piece = paint_curve(
            mesh,
            SurfacePoints.concatenate([stroke.picks[len(stroke.picks) - 1], pt]),
            kind=kind,
            spacing=self._spacing(),
        ).points
        stroke = replace(
            stroke,
            picks=SurfacePoints.concatenate([stroke.picks, pt]),
            pieces=(*stroke.pieces, piece),
        )
        state = replace(state, stroke=stroke)
        if snapped_end:
            return self._finished(state, end_corner), "finished"
        return state, "added"

    def _finished(self, state: SessionState, end_corner: int | None) -> SessionState:
        stroke = state.stroke
        assert stroke is not None
        if len(stroke.picks) < 2:
            raise InputError("a curve needs at least two picks")
        pts = stroke.points()
        if stroke.kind == "boundary":
            corners = state.corners
            if end_corner is None:
                corners = SurfacePoints.concatenate([corners, stroke.picks[len(stroke.picks) - 1]])
                end_corner = len(corners) - 1
            if end_corner == stroke.start_corner:
                raise InputError("a boundary curve cannot end at the corner it starts from")
            pc = PaintedCurve(
                SurfaceCurve(pts, kind="boundary"), (int(stroke.start_corner), int(end_corner))
            )
            return replace(state, corners=corners, curves=(*state.curves, pc), stroke=None)
        pc = PaintedCurve(SurfaceCurve(pts, kind="feature"), None)
        return replace(state, curves=(*state.curves, pc), stroke=None)

    def finish_curve(self) -> int:
        """End the stroke at its last pick, which snaps like an ``end=True`` pick (to a
        corner, or splitting a curve it lands on, else a new corner); returns the new curve's
        index."""
        st = self.state
        stroke = st.stroke
        if stroke is None:
            raise InputError("no curve is being painted")
        n = len(stroke.picks)
        if n < 2:
            raise InputError("a curve needs at least two picks")
        last = stroke.picks[n - 1]
        prev = replace(stroke, picks=stroke.picks[np.arange(n - 1)], pieces=stroke.pieces[:-1])
        new, _ = self._add(replace(st, stroke=prev), last, stroke.kind, True)
        self._commit(new)
        return len(self.state.curves) - 1

    def cancel_curve(self) -> None:
        """Drop the stroke being painted (its new corner too, if unused)."""
        if self.state.stroke is None:
            return
        self._commit(_pruned(replace(self.state, stroke=None)))

    def delete_curve(self, index: int) -> None:
        """Remove a curve; corners no other curve uses are removed with it."""
        i = self._curve_index(index)
        curves = self.state.curves[:i] + self.state.curves[i + 1 :]
        self._commit(_pruned(replace(self.state, curves=curves)))

    def _curve_index(self, index: int) -> int:
        n = len(self.state.curves)
        if (
            isinstance(index, bool)
            or not isinstance(index, (int, np.integer))
            or not (0 <= index < n)
        ):
            raise InputError(f"no curve {index!r}: there are {n} curves")
        return int(index)

    def _replace_curve(self, i: int, curve: SurfaceCurve, space: SpaceCurve | None) -> None:
        curves = list(self.state.curves)
        curves[i] = PaintedCurve(curve, curves[i].ends, space, curves[i].continuity)
        self._commit(replace(self.state, curves=tuple(curves)))

    # ------------------------------------------------------------------------ editing
    def _external(self):
        if not self.color.enabled:
            return None
        mesh = self._need_mesh()
        key = ("gradients", self.color.field)
        if key not in self._cache:
            self._cache[key] = vertex_gradients(mesh, scalar_field(mesh, self.color.field))
        g = self._cache[key]
        w, s = float(self.color.weight), int(self.color.sign)
        return lambda c: color_force(mesh, c, g, weight=w, sign=s)

    def set_color_attraction(
        self,
        *,
        enabled: bool,
        weight: float = 1.0,
        field: str = "luminance",
        sign: int = 1,
    ) -> ColorAttraction:
        """Colour attraction on or off, with its weight and scalar field (used by
        :meth:`smooth_curve`, :meth:`snake_step` and :meth:`edit_curve`)."""
        mesh = self._need_mesh()
        if enabled:
            scalar_field(mesh, field)  # raises a clear error for colour on an uncoloured mesh
        if not np.isfinite(weight) or weight < 0:
            raise InputError(f"colour weight must be >= 0, got {weight!r}")
        if sign not in (1, -1):
            raise InputError(f"sign must be 1 or -1, got {sign!r}")
        self.color = ColorAttraction(bool(enabled), float(weight), str(field), int(sign))
        return self.color

    def smooth_curve(
        self,
        index: int,
        *,
        w_fair: float = 1.0,
        w_curv: float = 0.0,
        max_iter: int = 500,
    ) -> int:
        """Relax a whole curve as a surface snake, ends fixed (with colour attraction when on).

        Returns the iterations run.
        """
        i = self._curve_index(index)
        res = relax_snake(
            self._need_mesh(),
            self.state.curves[i].curve,
            SnakeOptions(w_fair=w_fair, w_curv=w_curv, max_iter=max_iter),
            external=self._external(),
        )
        self._replace_curve(i, res.curve, None)
        return res.iterations

    def snake_step(self, index: int, *, w_fair: float = 1.0, w_curv: float = 0.0) -> float:
        """One relaxation iteration of a curve (the live-drag update); returns the largest
        move, model units."""
        i = self._curve_index(index)
        res = relax_snake(
            self._need_mesh(),
            self.state.curves[i].curve,
            SnakeOptions(w_fair=w_fair, w_curv=w_curv, max_iter=1),
            external=self._external(),
        )
        self._replace_curve(i, res.curve, None)
        return float(res.max_move[0]) if res.iterations else 0.0

    def nearest_sample(self, xyz: ArrayLike) -> tuple[int, int] | None:
        """The (curve, sample) nearest a 3-D point within ``tol.UI_PICK_RADIUS``, or None."""
        mesh = self._need_mesh()
        x = np.asarray(xyz, dtype=np.float64).reshape(3)
        i, s, d = self._nearest_sample(x, list(range(len(self.state.curves))))
        if i < 0 or d > tol.length(mesh, tol.UI_PICK_RADIUS, scale="bbox_diagonal"):
            return None
        return i, s

    def edit_curve(
        self,
        index: int,
        *,
        edit_index: int,
        section: int,
        target: ArrayLike,
        w_fair: float = 1.0,
        w_curv: float = 0.0,
    ) -> None:
        """Surface-snake edit: pull sample ``edit_index`` toward ``target`` (3-D) and relax
        the ``section`` samples either side, the rest of the curve unchanged (sec. 3.8.1)."""
        i = self._curve_index(index)
        res = edit_snake(
            self._need_mesh(),
            self.state.curves[i].curve,
            SnakeOptions(w_fair=w_fair, w_curv=w_curv, max_iter=500),
            edit_index=edit_index,
            section=section,
            target=np.asarray(target, dtype=np.float64),
        )
        self._replace_curve(i, res.curve, None)

    def fit_space_curve(self, index: int, *, n_control: int = 8) -> SpaceCurve:
        """Fit a B-spline space curve to a curve for control-vertex editing (sec. 3.3)."""
        i = self._curve_index(index)
        pc = self.state.curves[i]
        space = fit_space_curve(self._need_mesh(), pc.curve, n_control=n_control)
        self._replace_curve(i, pc.curve, space)
        return space

    def move_control_point(self, index: int, control: int, xyz: ArrayLike) -> None:
        """Drag control vertex ``control`` of curve ``index``'s space curve to ``xyz``; the
        surface curve follows by CurveAttract (its ends stay at their corners)."""
        i = self._curve_index(index)
        pc = self.state.curves[i]
        if pc.space is None:
            raise InputError(f"curve {i} has no space curve: fit one first")
        curve, space = move_control_point(self._need_mesh(), pc.curve, pc.space, control, xyz)
        pts = curve.points
        if pc.ends is not None:  # a boundary curve keeps its corners
            face, bary = pts.face.copy(), pts.bary.copy()
            for pos, c in ((0, pc.ends[0]), (-1, pc.ends[1])):
                face[pos], bary[pos] = self.state.corners.face[c], self.state.corners.bary[c]
            curve = SurfaceCurve(SurfacePoints(face, bary), kind=curve.kind)
        self._replace_curve(i, curve, space)

    # ------------------------------------------------------------------------ layout
    def status(self) -> NetworkStatus:
        """Which regions of the painted network are valid four-sided patches, and why not."""
        if "status" not in self._cache:
            st = self.state
            ids = st.boundary_ids
            self._cache["status"] = network_status(
                self._need_mesh(),
                st.corners,
                [st.curves[i].curve for i in ids],
                np.asarray([st.curves[i].ends for i in ids], dtype=np.int64).reshape(-1, 2),
            )
        return self._cache["status"]

    def layout(self):
        """The painted network as a :class:`meshfit.layout.Layout` (every region must be a
        valid four-sided patch)."""
        from meshfit.layout import layout_from_curves

        if "layout" in self._cache:
            return self._cache["layout"]
        mesh = self._need_mesh()
        status = self.status()
        if status.error:
            raise LayoutError(status.error)
        bad = [r for r in status.regions if not r.valid]
        if bad or not status.regions:
            what = f"region {bad[0].index}: {bad[0].reason}" if bad else "no regions"
            raise LayoutError(f"the curves do not make a layout yet: {what}")
        st = self.state
        ids = st.boundary_ids
        feats: list[list[SurfaceCurve]] = [[] for _ in status.regions]
        for i in st.feature_ids:
            c = st.curves[i].curve
            r = int(status.region_of_face[int(c.points.face[len(c) // 2])])
            feats[r].append(c)
        layout = layout_from_curves(
            mesh,
            st.corners,
            [st.curves[i].curve for i in ids],
            np.asarray([st.curves[i].ends for i in ids], dtype=np.int64),
            status.patches,
            feats,
            creases=self.creases(),
        )
        self._cache["layout"] = layout
        return layout

    def save_layout(self, path: str | os.PathLike) -> Path:
        """Write the layout JSON (atomically)."""
        from meshfit.layout import save_layout

        return save_layout(self.layout(), path, mesh=self._need_mesh())

    def set_layout(self, layout) -> None:
        """Replace the painted curves by a layout's corners, curves and feature curves."""
        st = self.state
        curves = [
            PaintedCurve(
                c,
                (int(layout.curve_ends[i, 0]), int(layout.curve_ends[i, 1])),
                continuity="C0" if bool(layout.creases[i]) else None,
            )
            for i, c in enumerate(layout.curves)
        ]
        curves += [PaintedCurve(f, None) for fs in layout.features for f in fs]
        self._commit(replace(st, corners=layout.corners, curves=tuple(curves), stroke=None))

    def load_layout(self, path: str | os.PathLike) -> None:
        """Read a layout JSON made for this mesh (checked) and edit its curves."""
        from meshfit.layout import load_layout

        self.set_layout(load_layout(path, self._need_mesh(), check_topology=False))

    def auto_layout(self) -> None:
        """A starting layout for the mesh, of any topology (replaces the painted curves;
        :func:`meshfit.layout.auto.auto_layout`)."""
        from meshfit.layout.auto import auto_layout

        self.set_layout(auto_layout(self._need_mesh()))

    # ------------------------------------------------------------------------ previews
    def patches(self):
        """The layout's patches as submeshes (cached until the next edit)."""
        from meshfit.layout import extract_patches

        if "patches" not in self._cache:
            self._cache["patches"] = extract_patches(self._need_mesh(), self.layout())
        return self._cache["patches"]

    def _patch(self, patch: int):
        ps = self.patches()
        if (
            isinstance(patch, bool)
            or not isinstance(patch, (int, np.integer))
            or not (0 <= patch < len(ps))
        ):
            raise InputError(f"no patch {patch!r}: the layout has {len(ps)} patches")
        return ps[int(patch)]

    def spring_preview(self, patch: int, *, level: int = 0):
        """The spring mesh of one patch relaxed up to ``level`` (coarse-to-fine previews:
        call with level 0, 1, 2... and show each; sec. 5.7, 5.13).

        Level 0 of a patch with more than
        :data:`meshfit.springs.preview.PREVIEW_MIN_VERTICES` vertices is a preview made on a
        coarse copy of the patch (:func:`meshfit.springs.preview.coarse_level0`: the planar
        map solved on the copy, the grid carried to the closest points of the patch and
        relaxed on the patch; several times faster cold, since the planar map's solve is
        most of a cold preview's time). Its points are face points of the patch; they lie
        within a fraction of a grid spacing of the exact level 0 of
        :func:`meshfit.springs.resample_patch` (bounds:
        :data:`meshfit.springs.preview.PREVIEW_MAX_OFFSET` and
        :data:`~meshfit.springs.preview.PREVIEW_MEDIAN_OFFSET`). Levels 1 and up, and every
        other caller of ``resample_patch``, use the exact map; the first of them makes it.

        Returns
        -------
        meshfit.springs.SpringMesh
        """
        from meshfit.springs import SpringOptions, resample_patch
        from meshfit.springs.preview import PREVIEW_MIN_VERTICES, coarse_level0

        key = ("springs", int(patch), int(level))
        if key not in self._cache:
            p = self._patch(patch)
            grid = None
            if int(level) == 0 and p.mesh.n_vertices > PREVIEW_MIN_VERTICES:
                grid = coarse_level0(p)
            if grid is None:
                grid = resample_patch(p, SpringOptions(level=int(level), metrics=False)).final
            self._cache[key] = grid
            self._cache[("grid", int(patch))] = grid
        return self._cache[key]

    def fit_patch(self, patch: int, *, controls: tuple[int, int] = (8, 8)) -> PatchFit:
        """Fit a B-spline to the patch's latest spring mesh at a control resolution (the
        live re-fit of the control-resolution sliders; sec. 6.2)."""
        from meshfit.bspline import fit_bspline, grid_parameters

        grid = self._cache.get(("grid", int(patch)))
        if grid is None:
            grid = self.spring_preview(patch, level=2)
        X = np.asarray(grid.xyz)
        nu, nv = X.shape[:2]
        mu, mv = (min(int(controls[0]), nu), min(int(controls[1]), nv))
        surface = fit_bspline(X, controls=(max(mu, 4), max(mv, 4)))
        S = surface.evaluate_grid(grid_parameters(nu), grid_parameters(nv))
        err = np.linalg.norm(X - S, axis=2)
        fit = PatchFit(int(patch), X, surface, S, err, float(np.sqrt(np.mean(err**2))))
        self._cache[("fit", int(patch))] = fit
        return fit

    def displacement_image(self, patch: int, *, controls: tuple[int, int] = (8, 8)):
        """Displacement-map image of a patch's fit: ``(h, w, 3) uint8`` with the vector
        displacement (T, B, N components) mapped from its symmetric range to 0..255."""
        from meshfit.displacement import displacement_map

        fit = self._cache.get(("fit", int(patch))) or self.fit_patch(patch, controls=controls)
        img = np.asarray(displacement_map(fit.surface, fit.grid_xyz, kind="vector").image)
        m = float(np.abs(img).max()) or 1.0
        return np.clip((img / m * 0.5 + 0.5) * 255.0, 0, 255).astype(np.uint8)

    def export(
        self,
        folder: str | os.PathLike,
        *,
        controls: tuple[int, int] = (16, 16),
        formats: tuple[str, ...] | None = None,
        units: str = "mm",
        up_axis: str = "auto",
        progress: Callable[[str, int, int], None] | None = None,
    ) -> list[Path]:
        """Fit the painted layout and write everything ``meshfit fit`` writes into ``folder``
        (:func:`meshfit.fit` with this layout and the chosen continuity); returns the files
        written."""
        from meshfit.pipeline import FitOptions, fit

        folder = Path(folder)
        before = set(folder.rglob("*")) if folder.is_dir() else set()
        kw = {} if formats is None else {"formats": tuple(formats)}
        opts = FitOptions(
            controls=(int(controls[0]), int(controls[1])),
            continuity="auto",
            units=units,
            up_axis=up_axis,
            **kw,
        )
        fit(self._need_mesh(), self.layout(), options=opts, out=folder, progress=progress)
        return sorted(p for p in folder.rglob("*") if p.is_file() and p not in before)

    # ------------------------------------------------------------------------ continuity
    def set_default_continuity(self, continuity: str) -> None:
        """The continuity of every boundary without a choice of its own: "C0" or "G1"."""
        c = str(continuity).upper()
        if c not in CONTINUITY:
            raise InputError(f"continuity must be C0 or G1, got {continuity!r}")
        self.default_continuity = c
        self._cache.pop("layout", None)

    def set_curve_continuity(self, index: int, continuity: str | None) -> None:
        """Choose C0 or G1 across boundary curve ``index`` (None: the default); undoable."""
        i = self._curve_index(index)
        pc = self.state.curves[i]
        if pc.ends is None:
            raise InputError(f"curve {i} is a feature curve: continuity is chosen on boundaries")
        c = None if continuity in (None, "default") else str(continuity).upper()
        if c is not None and c not in CONTINUITY:
            raise InputError(f"continuity must be C0, G1 or default, got {continuity!r}")
        curves = list(self.state.curves)
        curves[i] = replace(pc, continuity=c)
        self._commit(replace(self.state, curves=tuple(curves)))

    def curve_continuity(self, index: int) -> str:
        """The continuity a fit uses across boundary curve ``index``."""
        pc = self.state.curves[self._curve_index(index)]
        return pc.continuity or self.default_continuity

    def creases(self) -> NDArray[np.bool_]:
        """Per boundary curve (in layout order): whether a fit keeps it C0, ``(nk,) bool``
        (the layout's ``creases``, which a fit with continuity "auto" leaves C0)."""
        st = self.state
        return np.asarray(
            [(st.curves[i].continuity or self.default_continuity) == "C0" for i in st.boundary_ids],
            dtype=bool,
        )

    # ------------------------------------------------------------------------ the fit
    def fit_model(
        self,
        *,
        options=None,
        progress: Callable[[str, int, int], None] | None = None,
        cancel: threading.Event | None = None,
    ):
        """Fit the whole painted layout in memory (:func:`meshfit.fit`) with the chosen
        continuity: C0 across the curves chosen C0 (or by default), G1 elsewhere.

        Parameters
        ----------
        options : meshfit.pipeline.FitOptions, optional
            Controls, map kind, units...; its continuity, formats and report are replaced
            (continuity per curve, nothing written).
        progress : callable(stage, done, total), optional
        cancel : threading.Event, optional
            Set it to stop the fit at its next progress step
            (:class:`meshfit.ui.fitting.FitCancelled` is raised; the last result stays).

        Returns
        -------
        meshfit.FitResult
            Also kept as :attr:`result`.
        """
        from meshfit.pipeline import FitOptions, fit
        from meshfit.ui.fitting import FitCancelled

        opts = replace(options or FitOptions(), continuity="auto", formats=(), report=False)

        def tick(stage: str, done: int, total: int) -> None:
            if cancel is not None and cancel.is_set():
                raise FitCancelled(f"fit cancelled at stage {stage}")
            if progress is not None:
                progress(stage, done, total)

        result = fit(self._need_mesh(), self.layout(), options=opts, progress=tick)
        self.result = result
        return result

    def _need_result(self):
        if self.result is None:
            raise InputError("no fit yet: fit the model first")
        return self.result

    def refit_patch(self, patch: int, *, controls: tuple[int, int]):
        """Re-fit one patch of the last fit at a control resolution (its spring mesh kept);
        the other patches stay as they are. Returns the new result."""
        from meshfit.ui.fitting import refit_patch

        self.result = refit_patch(self._need_result(), patch, controls)
        return self.result

    def refit_all(self, *, controls: tuple[int, int]):
        """Re-fit every patch of the last fit from its spring mesh at a control resolution
        (the whole-model preview; seams are closed by the next whole fit)."""
        from meshfit.ui.fitting import refit_patch

        result = self._need_result()
        for p in range(len(result.patches)):
            result = refit_patch(result, p, controls)
        self.result = result
        return result

    def brush_map(self, patch: int, xyz: ArrayLike, *, radius: float, amount: float):
        """Paint on a patch's map: raise (``amount`` > 0) or lower the displaced surface
        around the texel nearest ``xyz`` and rebuild the result.

        Parameters
        ----------
        patch : int
        xyz : (3,) float64
            The brush's centre on the displaced surface, model units.
        radius : float
            Brush radius, model units.
        amount : float
            Displacement at the centre, model units.
        """
        from meshfit.ui.fitting import brush_map, texel_of

        result = self._need_result()
        if not (np.isfinite(radius) and radius > 0 and np.isfinite(amount)):
            raise InputError(
                f"a brush needs a radius > 0 and a finite amount, got {radius}, {amount}"
            )
        texel = texel_of(result, patch, np.asarray(xyz, dtype=np.float64))
        grid = result.patches[int(patch)].displaced()
        step = float(
            np.mean([np.linalg.norm(np.diff(grid, axis=k), axis=2).mean() for k in (0, 1)])
        )
        r_texels = max(float(radius) / max(step, 1e-300), 0.5)
        self.result = brush_map(result, patch, texel, radius=r_texels, amount=amount)
        return self.result

    def export_fit(
        self,
        folder: str | os.PathLike,
        *,
        formats: tuple[str, ...],
        units: str = "mm",
        up_axis: str = "auto",
    ) -> list[Path]:
        """Write the last fit in ``formats`` (any of :data:`meshfit.pipeline.FORMATS`) with
        the units and up axis the exports declare; returns the files written."""
        from meshfit.pipeline import FitOptions

        result = self._need_result()
        if not formats:
            raise InputError("choose at least one format to export")
        checked = FitOptions(formats=tuple(formats), units=units, up_axis=up_axis)
        result = replace(
            result, options=replace(result.options, units=checked.units, up_axis=checked.up_axis)
        )
        files = result.export(folder, formats=checked.formats)
        return sorted(Path(folder) / f for fs in files.values() for f in fs)

    # ------------------------------------------------------------------------ session file
    def _points_json(self, sp: SurfacePoints) -> str:
        """JSON of a point set, cached per (immutable) object: an edit re-serialises only the
        curve it changed."""
        hit = self._json_parts.get(id(sp))
        if hit is not None and hit[0] is sp:
            return hit[1]
        text = json.dumps(_sp_to_json(sp))
        self._json_parts[id(sp)] = (sp, text)
        return text

    def to_json(self) -> str:
        """The whole editable state as versioned JSON (the autosave format)."""
        return self._json_of(self.state, self._need_mesh(), self._fingerprint)

    def _json_of(self, st: SessionState, mesh: Mesh, fingerprint: str) -> str:
        with self._json_lock:
            return self._json_unlocked(st, mesh, fingerprint)

    def _json_unlocked(self, st: SessionState, mesh: Mesh, fingerprint: str) -> str:
        head = {
            "meshfit_ui_session": SESSION_VERSION,
            "mesh": {
                "name": mesh.name,
                "fingerprint": fingerprint,
                "n_vertices": mesh.n_vertices,
                "n_faces": mesh.n_faces,
            },
        }
        used = {id(st.corners)}
        curves = []
        for pc in st.curves:
            pts = pc.curve.points
            used.add(id(pts))
            ends = "null" if pc.ends is None else json.dumps(list(pc.ends))
            body = self._points_json(pts)[1:-1]  # '"n": ..., "face": "...", "bary": "..."'
            cont = "" if pc.continuity is None else f'"continuity": "{pc.continuity}", '
            curves.append(f'{{"kind": {json.dumps(pc.kind)}, "ends": {ends}, {cont}{body}}}')
        stroke = "null"
        if st.stroke is not None:
            used.update(id(p) for p in (st.stroke.picks, *st.stroke.pieces))
            pieces = ", ".join(self._points_json(p) for p in st.stroke.pieces)
            stroke = (
                f'{{"kind": {json.dumps(st.stroke.kind)}, '
                f'"start_corner": {json.dumps(st.stroke.start_corner)}, '
                f'"picks": {self._points_json(st.stroke.picks)}, "pieces": [{pieces}]}}'
            )
        if len(self._json_parts) > 4 * (len(used) + 8):  # forget curves no longer in the state
            self._json_parts = {k: v for k, v in self._json_parts.items() if k in used}
        return (
            json.dumps(head)[:-1]
            + f', "corners": {self._points_json(st.corners)}, "curves": [{", ".join(curves)}]'
            + f', "stroke": {stroke}}}'
        )

    def restore(self, path: str | os.PathLike) -> None:
        """Load a session file (e.g. the autosave after a crash) for the open mesh; undoable."""
        mesh = self._need_mesh()
        p = Path(path)
        try:
            doc = read_json_file(p)
        except (OSError, InputError) as exc:
            why = str(exc).removeprefix(f"{p}: ")
            raise InputError(f"{p}: not a readable session file ({why})") from None
        if not isinstance(doc, dict) or doc.get("meshfit_ui_session") not in READ_VERSIONS:
            versions = " or ".join(map(str, READ_VERSIONS))
            raise InputError(f"{p}: not a meshfit session file of version {versions}")
        meta = doc.get("mesh")
        if not isinstance(meta, dict) or meta.get("fingerprint") != self._fingerprint:
            raise InputError(f"{p}: the session was saved for another mesh")
        try:
            state = self._parse_session(doc, p, mesh)
        except (KeyError, TypeError, AttributeError, ValueError, IndexError, OverflowError) as e:
            what = f"{type(e).__name__}: {e}" if str(e) else type(e).__name__
            raise InputError(f"{p}: not a valid session file ({what})") from None
        self._commit(state)

    def _parse_session(self, doc: dict, p: Path, mesh: Mesh) -> SessionState:
        """The state a session document holds (InputError, or the Python errors of a key
        missing or of a wrong type, which :meth:`restore` turns into one)."""
        corners = _sp_from_json(doc["corners"], f"{p}: corners")
        curves = []
        for i, c in enumerate(doc.get("curves", [])):
            kind = c.get("kind")
            if kind not in ("boundary", "feature"):
                raise InputError(f"{p}: curve {i}: bad kind {kind!r}")
            ends = c.get("ends")
            if kind == "boundary":
                if not (isinstance(ends, list) and len(ends) == 2):
                    raise InputError(f"{p}: curve {i}: a boundary curve needs two corner ends")
                ends = (int(ends[0]), int(ends[1]))
                if not all(0 <= e < len(corners) for e in ends):
                    raise InputError(f"{p}: curve {i}: corner index out of range")
            else:
                ends = None
            sp = _sp_from_json(c, f"{p}: curve {i}")
            _check_on_mesh(mesh, sp, f"{p}: curve {i}")
            cont = c.get("continuity")
            if cont not in (None, *CONTINUITY):
                raise InputError(f"{p}: curve {i}: continuity must be C0 or G1, got {cont!r}")
            curves.append(PaintedCurve(SurfaceCurve(sp, kind=kind), ends, None, cont))
        _check_on_mesh(mesh, corners, f"{p}: corners")
        stroke = None
        s = doc.get("stroke")
        if s:
            picks = _sp_from_json(s["picks"], f"{p}: stroke")
            _check_on_mesh(mesh, picks, f"{p}: stroke")
            stroke = Stroke(
                s["kind"],
                picks,
                s.get("start_corner"),
                tuple(_sp_from_json(q, f"{p}: stroke piece") for q in s.get("pieces", [])),
            )
        return SessionState(corners, tuple(curves), stroke)


def _move_aside(path: Path) -> Path:
    """Rename ``path`` to the first free ``<stem>.unreadable-<n><suffix>`` beside it."""
    n = 1
    while (to := path.with_name(f"{path.stem}.unreadable-{n}{path.suffix}")).exists():
        n += 1
    path.rename(to)
    return to


def _check_on_mesh(mesh: Mesh, sp: SurfacePoints, where: str) -> None:
    if len(sp) and (sp.face.min() < 0 or sp.face.max() >= mesh.n_faces):
        raise InputError(f"{where}: face index out of range 0..{mesh.n_faces - 1}")


def _pruned(state: SessionState) -> SessionState:
    """Drop corners no boundary curve or stroke uses; renumber the ends."""
    used = set()
    for pc in state.curves:
        if pc.ends is not None:
            used.update(pc.ends)
    if state.stroke is not None and state.stroke.start_corner is not None:
        used.add(state.stroke.start_corner)
    keep = [c for c in range(len(state.corners)) if c in used]
    if len(keep) == len(state.corners):
        return state
    new_id = {c: k for k, c in enumerate(keep)}
    corners = state.corners[np.asarray(keep, dtype=np.int64)]
    curves = tuple(
        pc if pc.ends is None else replace(pc, ends=(new_id[pc.ends[0]], new_id[pc.ends[1]]))
        for pc in state.curves
    )
    stroke = state.stroke
    if stroke is not None and stroke.start_corner is not None:
        stroke = replace(stroke, start_corner=new_id[stroke.start_corner])
    return replace(state, corners=corners, curves=curves, stroke=stroke)
