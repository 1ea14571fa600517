"""Files of the fit: deterministic ``.npz`` arrays, JSON, content keys and hashes.

Everything the fit writes goes through here: arrays are stored uncompressed with fixed zip
timestamps (the same inputs give the same bytes), JSON goes through one encoder that knows
numpy scalars, and every file is written atomically (:mod:`meshfit._atomic`).
"""

from __future__ import annotations

import hashlib
import io
import json
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from meshfit._atomic import atomic_write, write_text
from meshfit._version import __version__
from meshfit.mesh import Mesh

#: version of the stage files, the fit files and the summary
PIPELINE_FORMAT = 3


def mesh_hash(mesh: Mesh) -> str:
    """SHA-256 of a mesh's vertex and face arrays (the content key of every stage)."""
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(mesh.vertices, dtype="<f8").tobytes())
    h.update(np.ascontiguousarray(mesh.faces, dtype="<i8").tobytes())
    return h.hexdigest()


def content_key(*parts: Any) -> str:
    text = json.dumps([PIPELINE_FORMAT, __version__, *parts], sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:20]


def save_npz(path: Path, arrays: dict[str, NDArray]) -> Path:
    """A deterministic ``.npz`` (fixed zip timestamps), written atomically.

    The arrays are stored, not deflated: deflating costs seconds on a large fit and the
    stage files are a cache, not a deliverable.
    """

    def write(tmp: str) -> None:
        with zipfile.ZipFile(tmp, "w", compression=zipfile.ZIP_STORED) as zf:
            for name in sorted(arrays):
                buf = io.BytesIO()
                np.lib.format.write_array(buf, np.ascontiguousarray(arrays[name]))
                info = zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0))
                info.compress_type = zipfile.ZIP_STORED
                info.external_attr = 0o644 << 16
                zf.writestr(info, buf.getvalue())

    return atomic_write(path, write)


def load_npz(path: Path) -> dict[str, NDArray]:
    with np.load(path, allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


def as_bytes(data: Any) -> NDArray[np.uint8]:
    """JSON text as a uint8 array (stored in stage ``.npz`` files without pickling)."""
    return np.frombuffer(json.dumps(data, default=json_default).encode(), dtype=np.uint8)


def from_bytes(a: NDArray[np.uint8]) -> Any:
    return json.loads(np.asarray(a, dtype=np.uint8).tobytes().decode())


def untimed(rows: list[dict]) -> list[dict]:
    """Rows without wall times: stage files hold only what the inputs determine (the same
    bytes on every run)."""
    return [{k: v for k, v in r.items() if k != "seconds"} for r in rows]


def write_json(path: Path, data: Any) -> Path:
    return write_text(path, json.dumps(data, indent=2, default=json_default) + "\n")


def json_default(o: Any) -> Any:
    if isinstance(o, np.integer):
        return int(o)
    if isinstance(o, np.floating):
        return float(o)
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def sha_file(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()
