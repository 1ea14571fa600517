"""File access of the web app: only the files the user names, uploads capped and validated.

A :class:`FilePolicy` holds the files named on the command line and one working folder. A
path typed into the app is accepted only when it resolves (symbolic links followed) to one of
the named files or to a file inside the working folder, with an allowed suffix. Uploaded
meshes are checked for size and suffix, written to a private temporary folder, read with
the ordinary mesh reader and validated like any input; nothing is ever unpickled.
"""

from __future__ import annotations

import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

from meshfit.errors import InputError
from meshfit.mesh import FORMATS, Mesh, read_mesh_arrays

__all__ = ["DEFAULT_UPLOAD_LIMIT", "FilePolicy", "mesh_from_upload"]

#: largest mesh upload accepted, bytes (200 MB: a few million triangles of binary PLY)
DEFAULT_UPLOAD_LIMIT = 200 * 1024 * 1024

LAYOUT_SUFFIXES = (".json",)
#: mesh formats accepted as uploads: self-contained ones only (a ``.gltf`` may name external
#: buffer files, which an upload must not make the server read)
UPLOAD_SUFFIXES = tuple(s for s in FORMATS if s != ".gltf")


def _resolve(path: str | os.PathLike) -> Path:
    return Path(os.path.expanduser(str(path))).resolve()


@dataclass
class FilePolicy:
    """Which paths the app may read and write.

    Parameters
    ----------
    workdir : path
        Folder the app may read and write files in (and below).
    named : list of path
        Files named on the command line (mesh, layout, autosave): always allowed.
    max_upload : int
        Upload size cap, bytes.
    """

    workdir: Path
    named: list[Path] = field(default_factory=list)
    max_upload: int = DEFAULT_UPLOAD_LIMIT

    def __post_init__(self) -> None:
        self.workdir = _resolve(self.workdir)
        self.named = [_resolve(p) for p in self.named]

    def allow(self, path: str | os.PathLike) -> Path:
        """Add a file the user named (e.g. on the command line); returns it resolved."""
        p = _resolve(path)
        if p not in self.named:
            self.named.append(p)
        return p

    def check(
        self, path: str | os.PathLike, *, suffixes: tuple[str, ...], write: bool = False
    ) -> Path:
        """The resolved path if the app may use it, else :class:`InputError`.

        Parameters
        ----------
        path : str or PathLike
            As typed by the user; relative paths are relative to ``workdir``.
        suffixes : tuple of str
            Allowed file suffixes (lower case, with the dot).
        write : bool
            The file will be written: its folder must exist.

        Raises
        ------
        meshfit.errors.InputError
            Empty path, wrong suffix, a path outside the working folder that was not named on
            the command line, a missing file to read or a missing folder to write into.
        """
        text = str(path).strip()
        if not text or "\x00" in text:
            raise InputError("no file name given")
        p = Path(os.path.expanduser(text))
        if not p.is_absolute():
            p = self.workdir / p
        p = p.resolve()
        if p.suffix.lower() not in suffixes:
            raise InputError(f"{text}: only {', '.join(suffixes)} files are allowed here")
        inside = p == self.workdir or self.workdir in p.parents
        if not inside and p not in self.named:
            raise InputError(
                f"{text}: outside the allowed folder {self.workdir} and not named on the "
                "command line; refused"
            )
        if write:
            if not p.parent.is_dir():
                raise InputError(f"{text}: folder {p.parent} does not exist")
        elif not p.is_file():
            raise InputError(f"{text}: no such file")
        return p

    def check_folder(self, path: str | os.PathLike) -> Path:
        """A folder inside ``workdir`` to write exports into (created if missing)."""
        text = str(path).strip()
        if not text or "\x00" in text:
            raise InputError("no folder name given")
        p = Path(os.path.expanduser(text))
        if not p.is_absolute():
            p = self.workdir / p
        p = p.resolve()
        if not (p == self.workdir or self.workdir in p.parents):
            raise InputError(f"{text}: outside the allowed folder {self.workdir}; refused")
        p.mkdir(parents=True, exist_ok=True)
        return p


def mesh_from_upload(name: str, content: bytes, *, max_bytes: int = DEFAULT_UPLOAD_LIMIT) -> Mesh:
    """Validate an uploaded mesh file and load it.

    Parameters
    ----------
    name : str
        The file name the browser sent (only its suffix is used).
    content : bytes
        The file's bytes.
    max_bytes : int, keyword-only
        Size cap.

    Returns
    -------
    Mesh
        Validated (not repaired); named after the upload's base name.

    Raises
    ------
    meshfit.errors.InputError
        Too large, empty, or an unknown suffix.
    meshfit.errors.MeshFileError, meshfit.errors.MeshValidationError
        The content is no readable mesh, or not a valid one.
    """
    base = Path(str(name).replace("\\", "/")).name
    suffix = Path(base).suffix.lower()
    if len(content) > max_bytes:
        raise InputError(
            f"upload {base!r} is {len(content):,} bytes; the limit is {max_bytes:,} bytes"
        )
    if not content:
        raise InputError(f"upload {base!r} is empty")
    allowed = UPLOAD_SUFFIXES
    if suffix not in allowed:
        raise InputError(f"upload {base!r}: only {', '.join(allowed)} mesh files are accepted")
    with tempfile.TemporaryDirectory(prefix="meshfit-upload-") as tmp:
        path = Path(tmp) / f"upload{suffix}"
        path.write_bytes(content)
        raw = read_mesh_arrays(path)
        return Mesh(raw.vertices, raw.faces, raw.vertex_colors, name=base)
