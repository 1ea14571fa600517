"""Map images: OpenEXR float32 and 16-bit PNG with the value range in the text metadata.

Orientation: the texture convention of OpenEXR, USD and Blender. Image x (columns, left to
right) runs along u and image y along v with row 0 at the top, i.e. at ``v = 1``: a map's
texel ``values[i, j]`` at ``(u, v) = (i / (h - 1), j / (w - 1))`` is pixel ``(row w - 1 -
j, column i)`` of a ``w`` rows by ``h`` columns image, so a renderer that samples the image
at texture coordinate ``(u, v)`` (origin at the lower left) reads the map there. Files of
format 2 and older stored rows along u; they are read as they were written.

Channels: a vector map's file holds its components in the order of tangent-space vector
displacement maps, R = T (tangent), G = N (normal), B = B (bitangent): the order Blender's
Vector Displacement node reads in Tangent Space (R along the tangent, G along the normal, B
along the bitangent) and Maya's and Mudbox's tangent-space vector displacement use (x
tangent, y normal, z binormal), so the image plugs straight into such a node with no
swizzle. In memory a map keeps ``(T, B, N)`` (:mod:`meshfit.displacement.maps`); reading
swaps back. Bump maps keep ``(T, B, N)`` as RGB, the tangent-space normal-map convention (R
tangent, G bitangent, B normal; a flat map is blue). Vector files of format 2 and older hold
``(T, B, N)`` and are read as they were written; a file without metadata read as a vector
map is taken as written in today's order.

Every kind is written and read back: vector and bump maps as three channels, scalar and
magnitude maps as one (a grey image). EXR files hold the float32 values (``RGB`` for
3-channel maps, ``Y`` for 1-channel maps) and string header attributes ``meshfit_map``
(format version), ``meshfit_kind`` and ``meshfit_frame``. PNG files hold values quantised to
16 bits over ``[min, max]``: pixel ``q`` stands for ``min + q / 65535 (max - min)``; a
``tEXt`` chunk with keyword ``meshfit`` holds JSON ``{"meshfit_map", "kind", "min", "max",
"frame"}``. Format 1 files name scalar maps ``"normal"``; they are read as scalar maps. An
image edited elsewhere that lost its metadata is read back by passing ``kind`` (and for PNG
``value_range``); a one-channel kind saved by an editor as RGB is read as the mean of its
channels. Files are written to a temporary name and renamed.
"""

from __future__ import annotations

import io
import json
import os
from pathlib import Path

import numpy as np
import OpenEXR
import png

from meshfit._atomic import atomic_write
from meshfit.displacement.maps import FRAME, KINDS, DisplacementMap, canonical_kind
from meshfit.errors import ImageFileError, InputError

__all__ = ["from_image", "read_exr", "read_png", "to_image", "write_exr", "write_png"]

#: version of the metadata written to map images (1: scalar maps were named "normal";
#: 2: image rows along u; 3: the texture orientation and the vector channel order of the
#: module docstring)
MAP_FORMAT = 3
#: file channel c of a vector map of format 3 holds its in-memory component
#: ``VECTOR_CHANNELS[c]``: R = T, G = N, B = B (tangent-space vector displacement)
VECTOR_CHANNELS = (0, 2, 1)


def to_image(values: np.ndarray) -> np.ndarray:
    """A map's ``(h, w, c)`` values (texel ``[i, j]`` at ``(u_i, v_j)``) as a ``(w, h, c)``
    image in texture orientation: x along u, y along v, row 0 at ``v = 1``."""
    return np.ascontiguousarray(np.swapaxes(values, 0, 1)[::-1])


def from_image(image: np.ndarray, fmt: int = MAP_FORMAT) -> np.ndarray:
    """The inverse of :func:`to_image` for a file of format ``fmt`` (older formats stored
    the values as they are)."""
    if fmt < 3:
        return image
    return np.swapaxes(image[::-1], 0, 1)


def _channel_order(kind: str, fmt: int) -> tuple[int, ...] | None:
    """The in-memory component each file channel of a ``kind`` map of format ``fmt`` holds
    (None: the file holds them in memory order)."""
    if kind == "vector" and fmt >= 3:
        return VECTOR_CHANNELS
    return None


def _to_file(values: np.ndarray, kind: str) -> np.ndarray:
    """A map's ``(h, w, c)`` values as the image written today: texture orientation, file
    channel order."""
    order = _channel_order(kind, MAP_FORMAT)
    return to_image(values if order is None else values[:, :, order])


def _from_file(image: np.ndarray, kind: str, fmt: int) -> np.ndarray:
    """The inverse of :func:`_to_file` for a file of format ``fmt`` holding a ``kind`` map
    (a vector file read as a one-channel kind has been averaged: no order to undo)."""
    order = _channel_order(kind, fmt)
    if order is not None and image.shape[2] == len(order):
        image = image[:, :, np.argsort(order)]
    return from_image(image, fmt)


def _file_kind(written, kind: str) -> str:
    """The kind a file's channels are laid out for: the kind its metadata names (``written``)
    when that is one, else ``kind``, the kind it is read as."""
    try:
        return canonical_kind(written)
    except InputError:
        return kind


def _format(value) -> int:
    """The format version a file's metadata names; files without one (an image edited
    elsewhere that lost its metadata) are taken as written in today's convention."""
    try:
        return int(value)
    except (TypeError, ValueError):
        return MAP_FORMAT


_COMPRESSION = {
    "none": OpenEXR.NO_COMPRESSION,
    "zip": OpenEXR.ZIP_COMPRESSION,
    "piz": OpenEXR.PIZ_COMPRESSION,
    "pxr24": OpenEXR.PXR24_COMPRESSION,
    "b44": OpenEXR.B44_COMPRESSION,
    "dwaa": OpenEXR.DWAA_COMPRESSION,
}


def write_exr(dmap: DisplacementMap, path: str | os.PathLike, *, compression: str = "zip") -> None:
    """Write a map as an OpenEXR float32 image.

    Channels ``RGB`` for vector and bump maps, ``Y`` for scalar and magnitude maps. A vector
    map's channels are R = T, G = N, B = B, the order of tangent-space vector displacement
    in Blender (Vector Displacement node, Tangent Space), Maya and Mudbox, so the file feeds
    such a node as it is; a bump map's are R = T, G = B, B = N, the tangent-space normal-map
    order. See the module docstring.

    Parameters
    ----------
    dmap : DisplacementMap
    path : str or path
    compression : {"zip", "none", "piz", "pxr24", "b44", "dwaa"}
        ``zip``/``none``/``piz`` are lossless; ``pxr24`` (24-bit floats), ``b44`` and ``dwaa``
        are lossy (the thesis' compression game). Default ``zip``.
    """
    if compression not in _COMPRESSION:
        raise InputError(f"compression must be one of {tuple(_COMPRESSION)}, got {compression!r}")
    img = _to_file(dmap.image, dmap.kind)
    channels = {"RGB": img} if dmap.channels == 3 else {"Y": np.ascontiguousarray(img[:, :, 0])}
    header = {
        "compression": _COMPRESSION[compression],
        "type": OpenEXR.scanlineimage,
        "meshfit_map": str(MAP_FORMAT),
        "meshfit_kind": dmap.kind,
        "meshfit_frame": FRAME,
    }

    def write(tmp: str) -> None:
        with OpenEXR.File(header, channels) as f:
            f.write(tmp)

    atomic_write(path, write)


def read_exr(path: str | os.PathLike, *, kind: str | None = None) -> DisplacementMap:
    """Read a map from an OpenEXR image (``RGB`` or ``Y`` channels, any pixel type).

    ``kind`` overrides (or replaces missing) ``meshfit_kind`` metadata; ``"normal"`` (format
    1) is read as ``"scalar"``.
    """
    path = Path(path)
    if not path.is_file():
        raise ImageFileError(f"{path}: no such file")
    try:
        with OpenEXR.File(str(path)) as f:
            header = dict(f.header())
            ch = {k: np.asarray(v.pixels) for k, v in f.channels().items()}
    except Exception as exc:  # the binding raises plain RuntimeError on bad files
        raise ImageFileError(f"{path}: not a readable OpenEXR file ({exc})") from None
    missing = "no meshfit_kind in the header; pass kind="
    kind = _kind(path, kind or header.get("meshfit_kind"), missing)
    if "Y" in ch and KINDS[kind] == 1:
        vals = ch["Y"][:, :, None]
    elif "RGB" in ch:
        vals = ch["RGB"]
    elif {"R", "G", "B"} <= set(ch):
        vals = np.stack([ch["R"], ch["G"], ch["B"]], axis=-1)
    elif "Y" in ch:
        vals = ch["Y"][:, :, None]
    else:
        raise ImageFileError(f"{path}: expected RGB or Y channels, found {sorted(ch)}")
    if KINDS[kind] == 1 and vals.shape[2] == 3:  # a grey map saved by an editor as RGB
        vals = vals.astype(np.float64).mean(axis=2, keepdims=True)
    if vals.shape[2] != KINDS[kind]:
        raise ImageFileError(
            f"{path}: a {kind} map needs {KINDS[kind]} channels, not {vals.shape[2]}"
        )
    fmt = _format(header.get("meshfit_map"))
    vals = _from_file(vals, _file_kind(header.get("meshfit_kind"), kind), fmt)
    return DisplacementMap(np.ascontiguousarray(vals, dtype=np.float64), kind)


def _kind(path: Path, kind: str | None, missing: str) -> str:
    """The kind a file's metadata (or the caller) names, as one of ``KINDS``; ``missing``:
    what to say when there is none."""
    if kind is None:
        raise ImageFileError(f"{path}: {missing}")
    try:
        return canonical_kind(kind)
    except InputError:
        raise ImageFileError(f"{path}: unknown map kind {kind!r}") from None


def write_png(
    dmap: DisplacementMap,
    path: str | os.PathLike,
    *,
    value_range: tuple[float, float] | None = None,
) -> None:
    """Write a map as a 16-bit PNG (grey for scalar maps, RGB for 3-channel maps).

    Parameters
    ----------
    dmap : DisplacementMap
    path : str or path
    value_range : (float, float), optional
        Values mapped to pixel 0 and 65535; default the map's min and max (``[-1, 1]`` for
        bump maps). Values outside are clipped. The quantisation step is
        ``(max - min) / 65535``; the value stored is within half a step.
    """
    vals = dmap.values
    if value_range is None:
        lo, hi = (-1.0, 1.0) if dmap.kind == "bump" else (float(vals.min()), float(vals.max()))
    else:
        lo, hi = (float(x) for x in value_range)
    if not (np.isfinite(lo) and np.isfinite(hi)) or hi < lo:
        raise InputError(f"value_range must be finite with min <= max, got {(lo, hi)}")
    if hi == lo:
        hi = lo + 1.0
    q = np.rint((np.clip(vals, lo, hi) - lo) / (hi - lo) * 65535.0).astype(np.uint16)
    q = _to_file(q, dmap.kind)
    h, w, c = q.shape
    buf = io.BytesIO()
    png.Writer(w, h, bitdepth=16, greyscale=c == 1).write(buf, q.reshape(h, w * c).tolist())
    meta = {"meshfit_map": MAP_FORMAT, "kind": dmap.kind, "min": lo, "max": hi, "frame": FRAME}
    text = b"meshfit\x00" + json.dumps(meta).encode("latin-1")
    chunks = list(png.Reader(bytes=buf.getvalue()).chunks())
    chunks.insert(1, (b"tEXt", text))

    def write(tmp: str) -> None:
        with open(tmp, "wb") as fh:
            png.write_chunks(fh, chunks)

    atomic_write(path, write)


def read_png(
    path: str | os.PathLike,
    *,
    kind: str | None = None,
    value_range: tuple[float, float] | None = None,
) -> DisplacementMap:
    """Read a map from a PNG (grey or RGB, 8 or 16 bits, e.g. after editing).

    ``kind`` and ``value_range`` override (or replace missing) ``meshfit`` text metadata;
    ``"normal"`` (format 1) is read as ``"scalar"``.
    """
    path = Path(path)
    if not path.is_file():
        raise ImageFileError(f"{path}: no such file")
    meta: dict = {}
    raw = path.read_bytes()
    try:
        for ctype, data in png.Reader(bytes=raw).chunks():
            if ctype == b"tEXt" and data.startswith(b"meshfit\x00"):
                meta = json.loads(data[len(b"meshfit\x00") :].decode("latin-1"))
        w, h, rows, info = png.Reader(bytes=raw).asDirect()
        q = np.vstack([np.asarray(r, dtype=np.float64) for r in rows])
    except (png.Error, ValueError, json.JSONDecodeError) as exc:
        raise ImageFileError(f"{path}: not a readable PNG with meshfit metadata ({exc})") from None
    c = info["planes"]
    if info.get("alpha"):
        q = q.reshape(h, w, c)[:, :, : c - 1]
        c -= 1
    q = q.reshape(h, w, c)
    kind = _kind(path, kind or meta.get("kind"), "no meshfit metadata; pass kind= and value_range=")
    if value_range is None:
        if "min" not in meta or "max" not in meta:
            raise ImageFileError(f"{path}: no value range in the metadata; pass value_range=")
        value_range = (meta["min"], meta["max"])
    lo, hi = (float(x) for x in value_range)
    if KINDS[kind] == 1 and c == 3:  # an editor saved a grey map as RGB: take the mean
        q = q.mean(axis=2, keepdims=True)
        c = 1
    if c != KINDS[kind]:
        raise ImageFileError(f"{path}: a {kind} map needs {KINDS[kind]} channels, not {c}")
    vals = lo + q / float(2 ** info["bitdepth"] - 1) * (hi - lo)
    fmt = _format(meta.get("meshfit_map"))
    vals = np.ascontiguousarray(_from_file(vals, _file_kind(meta.get("kind"), kind), fmt))
    if kind == "bump":
        vals /= np.linalg.norm(vals, axis=-1, keepdims=True)
    return DisplacementMap(vals, kind)
