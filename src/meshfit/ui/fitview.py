"""The fit in the 3D view: one scene node per patch and layer, patch numbers, the selection.

:class:`FitLayers` draws a :class:`meshfit.FitResult` into a viser scene: per patch its
spring grid, its spline and its displaced surface, each coloured by patch or by deviation
from the scan (percent of the bounding-box diagonal, with a legend), and the patch numbers.
Each layer can be shown or hidden; re-drawing one patch replaces only that patch's nodes.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from meshfit.ui.fitting import RAMP, deviation_colors, deviation_percent, patch_colors

if TYPE_CHECKING:
    from meshfit.mesh import Mesh

__all__ = ["LAYERS", "FitLayers", "grid_lines", "legend_html"]

#: the fit's layers, as the view toggles name them
LAYERS = ("springs", "spline", "displaced")
#: most grid lines drawn across a spring mesh; finer grids are thinned to this
MAX_GRID_LINES = 24


def grid_lines(xyz: NDArray[np.float64], max_lines: int = MAX_GRID_LINES) -> NDArray[np.float64]:
    """Segments of a ``(nu, nv, 3)`` grid's lines, ``(n, 2, 3)``: every k-th line of each
    direction and the border, so that a fine level reads as a grid, not a filled patch."""
    x = np.asarray(xyz, dtype=np.float64)
    nu, nv = x.shape[:2]

    def keep(n: int) -> NDArray[np.int64]:
        k = max(1, int(np.ceil((n - 1) / max(max_lines - 1, 1))))
        return np.unique(np.r_[np.arange(0, n, k), n - 1])

    iu, iv = keep(nu), keep(nv)
    rows = x[iu]  # lines along v
    cols = x[:, iv]  # lines along u
    a = np.stack([rows[:, :-1], rows[:, 1:]], axis=2).reshape(-1, 2, 3)
    b = np.stack([cols[:-1, :], cols[1:, :]], axis=2).reshape(-1, 2, 3)
    return np.concatenate([a, b])


def legend_html(top: float, title: str) -> str:
    """The deviation legend: the colour ramp from 0 to ``top`` percent of the diagonal."""
    stops = ", ".join(f"rgb{tuple(c)}" for c in RAMP)
    ticks = "".join(f"<span>{top * q:.3g}</span>" for q in (0.0, 0.25, 0.5, 0.75))
    return (
        f'<div style="font-size:0.8em;padding:2px 0">{title}'
        f'<div style="height:12px;border-radius:3px;background:linear-gradient(to right, '
        f'{stops})"></div><div style="display:flex;justify-content:space-between">'
        f"{ticks}<span>&ge; {top:.3g} %</span></div>"
        "<div>percent of the bounding-box diagonal</div></div>"
    )


class FitLayers:
    """The scene nodes of a fit.

    Parameters
    ----------
    scene : viser.SceneApi
    mesh : Mesh
        The scan (deviations are measured against it).
    """

    def __init__(self, scene, mesh: Mesh) -> None:
        self.scene = scene
        self.mesh = mesh
        self.visible = {"springs": False, "spline": False, "displaced": True}
        self.deviation = True
        self.nodes: dict[tuple[str, int], object] = {}
        self.labels: dict[int, object] = {}
        #: per patch and surface layer: deviation from the scan, percent of the diagonal
        self.dev: dict[tuple[str, int], NDArray[np.float64]] = {}
        self.top = 1.0
        self.colors = np.zeros((0, 3), np.uint8)
        self.show_labels = True

    # -------------------------------------------------------------------- drawing
    def draw(self, result) -> None:
        """Draw every patch of ``result`` (the legend's top: the spline's deviation)."""
        self.clear()
        n = len(result.patches)
        self.colors = patch_colors(n)
        self.dev = {}
        for p in range(n):
            self._measure(result, p)
        spline = np.concatenate([self.dev[("spline", p)].ravel() for p in range(n)])
        self.top = float(max(np.percentile(spline, 99.0), 1e-6)) if spline.size else 1.0
        for p in range(n):
            self.draw_patch(result, p, measure=False)

    def _measure(self, result, p: int) -> None:
        pf = result.patches[p]
        self.dev[("spline", p)] = deviation_percent(self.mesh, self._spline(pf))
        self.dev[("displaced", p)] = deviation_percent(self.mesh, pf.displaced())

    @staticmethod
    def _spline(pf) -> NDArray[np.float64]:
        from meshfit.bspline import grid_parameters

        nu, nv = pf.spring.shape[:2]
        return pf.surface.evaluate_grid(grid_parameters(nu), grid_parameters(nv))

    def draw_patch(self, result, p: int, *, measure: bool = True) -> None:
        """(Re)draw one patch's nodes; the other patches' nodes are not touched."""
        import trimesh

        from meshfit.ui.fitting import grid_triangles_of

        if measure:
            self._measure(result, p)
        pf = result.patches[p]
        for layer in LAYERS:
            old = self.nodes.pop((layer, p), None)
            if old is not None:
                old.remove()
        diag = self.mesh.bbox_diagonal
        self.nodes[("springs", p)] = self.scene.add_line_segments(
            f"/fit/springs/p{p}",
            grid_lines(pf.spring),
            (40, 40, 110),
            thickness=1.5,
            thickness_units="screen",
            visible=self.visible["springs"],
        )
        for layer, xyz in (("spline", self._spline(pf)), ("displaced", pf.displaced())):
            if self.deviation:
                colors = deviation_colors(self.dev[(layer, p)], self.top)
            else:
                colors = np.broadcast_to(self.colors[p], (xyz.shape[0] * xyz.shape[1], 3))
            tm = trimesh.Trimesh(
                xyz.reshape(-1, 3),
                grid_triangles_of(xyz.shape[:2]),
                vertex_colors=np.ascontiguousarray(colors),
                process=False,
            )
            self.nodes[(layer, p)] = self.scene.add_mesh_trimesh(
                f"/fit/{layer}/p{p}", tm, visible=self.visible[layer]
            )
        old = self.labels.pop(p, None)
        if old is not None:
            old.remove()
        centre = pf.displaced()
        c = centre[centre.shape[0] // 2, centre.shape[1] // 2]
        self.labels[p] = self.scene.add_label(
            f"/fit/labels/p{p}",
            f"{p}",
            position=tuple(c + 0.004 * diag * _outward(centre)),
            anchor="center-center",
            font_screen_scale=0.8,
            visible=self.show_labels,
        )

    def set_visible(self, layer: str, on: bool) -> None:
        self.visible[layer] = bool(on)
        for (name, _), h in self.nodes.items():
            if name == layer:
                h.visible = bool(on)

    def set_labels(self, on: bool) -> None:
        self.show_labels = bool(on)
        for h in self.labels.values():
            h.visible = bool(on)

    def clear(self) -> None:
        for h in [*self.nodes.values(), *self.labels.values()]:
            h.remove()
        self.nodes.clear()
        self.labels.clear()

    # -------------------------------------------------------------------- figures
    def figures(self, result, p: int) -> dict[str, float]:
        """A patch's deviations from the scan (percent of the diagonal): max and RMS of
        the spline and of the displaced surface at the spring points and the texels."""
        out = {}
        for layer in ("spline", "displaced"):
            d = self.dev.get((layer, p))
            if d is None:
                self._measure(result, p)
                d = self.dev[(layer, p)]
            out[f"{layer}_max"] = float(d.max())
            out[f"{layer}_rms"] = float(np.sqrt(np.mean(d**2)))
        return out


def _outward(grid: NDArray[np.float64]) -> NDArray[np.float64]:
    """Unit normal of a grid's middle cell (the side its label is lifted to)."""
    i, j = grid.shape[0] // 2, grid.shape[1] // 2
    i0, i1 = max(i - 1, 0), min(i + 1, grid.shape[0] - 1)
    j0, j1 = max(j - 1, 0), min(j + 1, grid.shape[1] - 1)
    n = np.cross(grid[i1, j] - grid[i0, j], grid[i, j1] - grid[i, j0])
    norm = float(np.linalg.norm(n))
    return n / norm if norm > 0 else np.zeros(3)
