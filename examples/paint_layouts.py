"""Paint the test layouts of igea, nefertiti and spot and save them as layout files.

Each layout is an n x n subdivided cube projected from the mesh centroid onto the surface
(n = 2: 24 four-sided patches, 26 corners, 48 boundary curves; n = 3: 54 patches), its edges
painted with ``meshfit.curves.paint_curve`` through projected picks. Patch 0 of igea gets
two feature curves in each direction. Every layout is checked by extracting its patches.

Usage::

    python examples/paint_layouts.py [DATA_DIR] [--out examples/layouts]

``DATA_DIR`` holds ``meshes/<name>.ply`` (default ``../shared/data``).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from meshfit.layout import extract_patches, layout_from_curves, save_layout
from meshfit.layout.cube import cube_layout
from meshfit.mesh import load_mesh
from meshfit.types import SurfaceCurve, SurfacePoints

#: mesh name -> (cube subdivision n: 6 n^2 patches, patch given feature curves or None,
#: projected picks per cube edge). Nefertiti uses the 3 x 3 cube: its 2 x 2 projection gives
#: a patch over the crown and back of the head with sides of lengths 7.6 : 1
LAYOUTS = {"igea": (2, 0, 24), "nefertiti": (3, None, 16), "spot": (2, None, 24)}
DIGITS = 12


def _rounded(points: SurfacePoints) -> SurfacePoints:
    b = np.clip(np.round(points.bary, DIGITS), 0.0, None)
    b[:, 2] = np.round(1.0 - b[:, 0] - b[:, 1], DIGITS + 2)
    return SurfacePoints(points.face, np.clip(b, 0.0, None))


def _compact(mesh, layout):
    """The layout with barycentrics rounded to ~12 digits (smaller files)."""

    def curve(c: SurfaceCurve) -> SurfaceCurve:
        return SurfaceCurve(_rounded(c.points), kind=c.kind)

    patches = [
        [(int(layout.patch_curves[p, s]), bool(layout.patch_reversed[p, s])) for s in range(4)]
        for p in range(layout.n_patches)
    ]
    return layout_from_curves(
        mesh,
        _rounded(layout.corners),
        [curve(c) for c in layout.curves],
        layout.curve_ends,
        patches,
        [[curve(f) for f in fs] for fs in layout.features],
    )


def main(argv: list[str] | None = None) -> int:
    here = Path(__file__).resolve().parent
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("data", nargs="?", default=str(here.parent.parent / "shared" / "data"))
    ap.add_argument("--out", default=str(here / "layouts"))
    ap.add_argument("--only", nargs="*", default=list(LAYOUTS))
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for name in args.only:
        n, feature_patch, picks = LAYOUTS[name]
        mesh = load_mesh(Path(args.data) / "meshes" / f"{name}.ply")
        t0 = time.perf_counter()
        layout = cube_layout(mesh, n=n, feature_patch=feature_patch, picks_per_curve=picks)
        layout = _compact(mesh, layout)
        t1 = time.perf_counter()
        patches = extract_patches(mesh, layout)
        t2 = time.perf_counter()
        area = sum(p.mesh.area for p in patches)
        path = save_layout(layout, out / f"{name}.json", mesh=mesh)
        print(
            f"{name}: {layout.n_patches} patches, {len(layout.curves)} curves, "
            f"{sum(len(c) for c in layout.curves)} curve points; painted in {t1 - t0:.1f} s, "
            f"extracted in {t2 - t1:.1f} s; area {area:.6g} of {mesh.area:.6g}; "
            f"{path} ({path.stat().st_size / 1e6:.2f} MB)"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
