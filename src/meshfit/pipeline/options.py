"""Options of the fit: one frozen dataclass for the user, a small view per stage.

:class:`FitOptions` holds every choice with its default (the command line and the web app
fill it); each stage reads only its own group
(:class:`meshfit.layout.auto.LayoutOptions`,
:class:`meshfit.springs.SpringOptions`, :class:`SplineOptions`, :class:`MapOptions`,
:class:`OutputOptions`), and a stage's cache key holds exactly that group, so changing an
output option never recomputes a spring mesh.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from meshfit._threads import n_workers
from meshfit.errors import InputError
from meshfit.layout.auto import MAX_SEED, LayoutOptions
from meshfit.springs import SpringOptions
from meshfit.springs.resample import check_spring_options

__all__ = [
    "FORMATS",
    "MAP_KINDS",
    "FitOptions",
    "LayoutOptions",
    "MapOptions",
    "OutputOptions",
    "SplineOptions",
    "SpringOptions",
    "stage_key",
]

#: kinds of map a fit makes (``FitOptions.map_kind``)
MAP_KINDS = ("vector", "scalar", "bump")
#: output formats of ``FitOptions.formats``
FORMATS = ("usd", "3dm", "iges", "step", "obj", "glb", "ply", "exr", "png")


@dataclass(frozen=True)
class FitOptions:
    """Options of :func:`meshfit.fit` (all have defaults).

    Attributes
    ----------
    controls : (int, int)
        Requested control resolution ``(mu, mv)`` per patch (default 16 x 16). A patch never
        gets more controls than its spring grid has points; with C0 stitching the counts along
        each shared curve are unified (:func:`meshfit.stitch.control_classes`).
    class_controls : mapping of int to int, or pairs
        Control counts of chosen equal-count classes, ``{class: count}`` (default none). The
        classes (patch directions linked by shared curves and opposite sides, which must
        share one count) are listed in ``summary["control_classes"]`` with their members and
        the largest count their spring grids allow; a count above that is capped (with a
        note). Stored as sorted ``(class, count)`` pairs.
    spline_smoothing : float
        Keep detail narrower than about this many knot spacings out of the splines, so that
        the maps hold it (``smoothing`` of :func:`meshfit.bspline.fit_bspline`; thesis sec.
        7.5; default 0: the plain least-squares fit, whose spline alone is closest to the
        input). With vector maps the displaced surface is the same either way; 0.5 suits
        maps that are edited or transferred.
    continuity : {"auto", "C0", "G1"}
        Continuity across shared boundaries (default ``"auto"``: G1 except across the
        layout's crease curves, which stay C0). Lower case is accepted.
    formats : tuple of str
        Outputs among :data:`FORMATS` (default usd, obj, exr: the USD stage for studio
        pipelines and Blender, the OBJ with its material for every other mesh tool, and the
        lossless EXR maps both of them reference; glb, png, ply and the CAD formats on
        request).
    patches : int, optional
        Patch count asked of the automatic layout (``layout="auto"``).
    layout_shape : bool, optional
        ``shape`` of :func:`meshfit.layout.auto.auto_layout`: move the base vertices so that
        the quads are square on the surface (default None: above 60 patches).
    drop_components_below : float
        Drop the mesh's components below this share of its area before the layout
        (default 0: none; the notes name those below 1% either way).
    remesh : {"auto", "on", "off"}
        Fit an even remesh of the input (:func:`meshfit.layout.even.even_remesh`: its
        creases kept, every vertex on the input) with the automatic layout: ``"auto"``
        (default) where needle triangles cover more than a tenth of its area (a CAD
        program's tessellation, whose cells fold; the notes say so and how far the remesh
        is from the input), ``"on"`` always, ``"off"`` never. A layout file is always laid
        on the input as it is.
    crease_angle : float, optional
        ``crease_angle`` of :func:`meshfit.layout.auto.auto_layout`: chains of edges
        sharper than this many degrees become patch boundaries, C0 with continuity
        ``"auto"`` (default 40; None: no creases).
    layout_seed : int
        ``seed`` of :func:`meshfit.layout.auto.auto_layout`: the rotation of the automatic
        layout's base mesh (default 0). Another rotation gives other patches where the
        summary's notes name slivers, tapered or bulging patches, or corners that turn back.
    spring_level : int, optional
        Final spring-mesh level (default: the level whose point count is closest to the
        patch's vertex count, :func:`meshfit.springs.resample_patch`).
    spring_max_points : int, optional
        Upper bound on a patch's final spring-mesh point count.
    spring_rescue : bool
        Make a patch's spring mesh again from an area-balanced map with light relaxation
        where the relaxed grid misses the patch by more than a grid spacing (default True;
        ``rescue`` of :func:`meshfit.springs.resample_patch`), and up to two levels finer
        where that still misses (without ``spring_level``), so that pleats, squeezed bulges
        and protrusions inside a patch are sampled; where neither is kept, the relaxed
        grid's last level is evened out along its grid lines in the planar map.
    spring_follow_folds : bool
        ``follow_folds`` of :func:`meshfit.springs.resample_patch`: spring vectors across a
        fold of the surface follow the grid line, so the grids cross curled rims (default
        False: with the rescue on, the grids it improves are those the rescue already
        handles, and the displaced error does not drop).
    map_kind : {"vector", "scalar", "bump"}
        What the maps hold (default ``"vector"``: the exact displacement of the spring grid,
        in the spline's frame). ``"scalar"``: a distance along the spline's normal (what a
        user paints, thesis fig. 7.4; the spline's normal at each seam makes the seams meet
        only where both sides agree, so values on crease seams go to 0). ``"bump"``: shading
        normals for renderers; the geometry is the spline. ``"normal"`` is read as scalar.
    map_shapes : {"matched", "native"}
        Resolution of the maps. ``"matched"`` (default): equal texel counts along every
        shared curve, the largest of each equal-count class
        (:func:`meshfit.stitch.match_map_shapes`), so the seams are crack-free at every
        output resolution: the exported meshes share their boundary vertices, and a renderer
        that tessellates the maps at its own rate opens no crack. It costs texels (each class
        takes its largest member's count). ``"native"``: each map at its spring grid's
        resolution; the displaced mesh is the spring mesh, crack-free only as tessellated at
        the maps' own resolutions (thesis sec. 8.2).
    workers : int, optional
        Threads for the per-patch stages (default: all cores).
    report : bool
        Write ``report.html`` with its images (default True).
    image_size : int
        Width and height of the report's renders, pixels (default 640).
    normal_errors : bool
        Also measure each patch's normal-distance fit error (eq. 6.2, a closest-point
        search per grid point; default False: the parametric error, eq. 6.1, only).
    units : str
        The length unit of the input's coordinates, declared by every export (USD, 3dm,
        IGES, STEP; :data:`meshfit.export.units.UNITS`; default ``"mm"``, what scanners
        write). Coordinates are never scaled.
    up_axis : {"auto", "y", "z"}
        The axis the exports declare as up (default ``"auto"``:
        :func:`meshfit.mesh.measures.up_axis`, z for models much taller along z than along
        y, else y). Coordinates are never turned.
    """

    controls: tuple[int, int] = (16, 16)
    class_controls: Any = ()
    continuity: str = "auto"
    spline_smoothing: float = 0.0
    formats: tuple[str, ...] = ("usd", "obj", "exr")
    patches: int | None = None
    layout_shape: bool | None = None
    layout_seed: int = 0
    crease_angle: float | None = 40.0
    drop_components_below: float = 0.0
    remesh: str = "auto"
    spring_level: int | None = None
    spring_max_points: int | None = None
    spring_rescue: bool = True
    spring_follow_folds: bool = False
    map_kind: str = "vector"
    map_shapes: str = "matched"
    workers: int | None = None
    report: bool = True
    image_size: int = 640
    normal_errors: bool = False
    units: str = "mm"
    up_axis: str = "auto"

    def __post_init__(self) -> None:  # noqa: C901 (one check per option, in order; to split by group)
        try:
            mu, mv = (int(c) for c in self.controls)
        except (TypeError, ValueError):
            raise InputError(f"controls must be two integers, got {self.controls!r}") from None
        if mu < 4 or mv < 4:
            raise InputError(f"controls must be at least 4 x 4, got {mu} x {mv}")
        object.__setattr__(self, "controls", (mu, mv))
        object.__setattr__(self, "class_controls", _class_pairs(self.class_controls))
        cont = str(self.continuity)
        cont = cont if cont == "auto" else cont.upper()
        if cont not in ("auto", "C0", "G1"):
            raise InputError(f"continuity must be 'auto', 'C0' or 'G1', got {self.continuity!r}")
        object.__setattr__(self, "continuity", cont)
        fm = tuple(str(f).strip().lower() for f in self.formats if str(f).strip())
        bad = [f for f in fm if f not in FORMATS]
        if bad:
            raise InputError(f"unknown output format {bad[0]!r}: choose from {', '.join(FORMATS)}")
        if "step" in fm:
            from meshfit.export import step_available

            if not step_available():
                raise InputError(
                    "STEP output needs OpenCASCADE: pip install 'meshfit[cad]' (cadquery-ocp)"
                )
        object.__setattr__(self, "formats", fm)
        kind = {"normal": "scalar"}.get(self.map_kind, self.map_kind)
        if kind not in MAP_KINDS:
            raise InputError(
                f"map_kind must be one of {', '.join(MAP_KINDS)}, got {self.map_kind!r}"
            )
        object.__setattr__(self, "map_kind", kind)
        if self.map_shapes not in ("matched", "native"):
            raise InputError(f"map_shapes must be 'native' or 'matched', got {self.map_shapes!r}")
        if self.workers is not None:
            n_workers(self.workers)  # an integer >= 1, else InputError
        if self.patches is not None and int(self.patches) < 1:
            raise InputError(f"patches must be >= 1, got {self.patches}")
        if self.layout_shape not in (None, True, False):
            raise InputError(f"layout_shape must be True, False or None, got {self.layout_shape!r}")
        seed = self.layout_seed
        if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
            raise InputError(f"layout_seed must be a whole number >= 0, got {seed!r}")
        if seed > MAX_SEED:
            raise InputError(f"layout_seed must be at most {MAX_SEED}, got {seed}")
        object.__setattr__(self, "layout_seed", int(seed))
        if not 0.0 <= float(self.drop_components_below) < 1.0:
            raise InputError(
                "drop_components_below must be a share of the area in [0, 1), got "
                f"{self.drop_components_below!r}"
            )
        object.__setattr__(self, "drop_components_below", float(self.drop_components_below))
        remesh = str(self.remesh).lower()
        if remesh not in ("auto", "on", "off"):
            raise InputError(f"remesh must be 'auto', 'on' or 'off', got {self.remesh!r}")
        object.__setattr__(self, "remesh", remesh)
        if self.crease_angle is not None:
            a = float(self.crease_angle)
            if not 0.0 < a < 180.0:
                raise InputError(f"crease_angle must be between 0 and 180 degrees, got {a}")
            object.__setattr__(self, "crease_angle", a)
        sm = self.spline_smoothing
        if isinstance(sm, bool) or not isinstance(sm, (int, float)) or not 0.0 <= sm < np.inf:
            raise InputError(f"spline_smoothing must be >= 0 knot spacings, got {sm!r}")
        object.__setattr__(self, "spline_smoothing", float(sm))
        if int(self.image_size) < 16:
            raise InputError(f"image_size must be >= 16 pixels, got {self.image_size}")
        from meshfit.export.units import unit

        object.__setattr__(self, "units", unit(self.units).name)
        check_spring_options(self.springs)  # (the spring stage's values, before any work)
        axis = str(self.up_axis).lower()
        if axis not in ("auto", "y", "z"):
            raise InputError(f"up_axis must be 'auto', 'y' or 'z', got {self.up_axis!r}")
        object.__setattr__(self, "up_axis", axis)

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> FitOptions:
        """Options from their JSON form (``asdict`` as a summary or ``fit.json`` holds them:
        lists for tuples), validated as on construction."""
        kw: dict[str, Any] = {k: tuple(v) if isinstance(v, list) else v for k, v in data.items()}
        return cls(**kw)

    @property
    def layout(self) -> LayoutOptions:
        """The automatic layout's group."""
        return LayoutOptions(
            patches=self.patches,
            seed=self.layout_seed,
            shape=self.layout_shape,
            crease_angle=self.crease_angle,
        )

    @property
    def springs(self) -> SpringOptions:
        """The spring-mesh stage's options (:class:`meshfit.springs.SpringOptions`)."""
        return SpringOptions(
            level=self.spring_level,
            max_points=self.spring_max_points,
            rescue=bool(self.spring_rescue),
            follow_folds=bool(self.spring_follow_folds),
            metrics=False,
        )

    @property
    def spline(self) -> SplineOptions:
        """The fitting stage's group."""
        return SplineOptions(
            self.controls,
            self.class_controls,
            self.continuity,
            self.normal_errors,
            self.spline_smoothing,
        )

    @property
    def maps(self) -> MapOptions:
        """The displacement and stitch stages' group."""
        return MapOptions(self.map_kind, self.map_shapes)

    @property
    def outputs(self) -> OutputOptions:
        """The exports' and the report's group."""
        return OutputOptions(self.formats, self.report, self.image_size, self.units, self.up_axis)


@dataclass(frozen=True)
class SplineOptions:
    """Control counts, continuity and the fit's error measure."""

    controls: tuple[int, int]
    class_controls: tuple[tuple[int, int], ...]
    continuity: str
    normal_errors: bool
    smoothing: float


@dataclass(frozen=True)
class MapOptions:
    """Kind and resolution of the displacement maps."""

    kind: str
    shapes: str


@dataclass(frozen=True)
class OutputOptions:
    """Files written from a fit."""

    formats: tuple[str, ...]
    report: bool
    image_size: int
    units: str
    up_axis: str


def stage_key(group: Any) -> dict[str, Any]:
    """An option group as JSON-ready data (part of a stage's content key)."""
    return {type(group).__name__: asdict(group)}


def _class_pairs(value: Any) -> tuple[tuple[int, int], ...]:
    """``class_controls`` as sorted ``(class, count)`` pairs, validated."""
    items = value.items() if isinstance(value, Mapping) else value
    try:
        pairs = [(int(c), int(n)) for c, n in items]
    except (TypeError, ValueError):
        raise InputError(
            f"class_controls must map class indices to counts, got {value!r}"
        ) from None
    seen: set[int] = set()
    for c, n in pairs:
        if c < 0:
            raise InputError(f"class_controls: class {c} is negative")
        if n < 4:
            raise InputError(f"class_controls: class {c} needs at least 4 controls, got {n}")
        if c in seen:
            raise InputError(f"class_controls: class {c} is given twice")
        seen.add(c)
    return tuple(sorted(pairs))
