"""Atomic file output: write to a temporary name in the target folder, then rename.

A crash or an exception leaves either the old file or the new one, never half of one. The
result gets the permissions an ordinary ``open(path, "w")`` would give (``0o666`` less the
umask), not the private ``0o600`` of a temporary file.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable
from pathlib import Path

__all__ = ["atomic_write", "remove_pending", "write_bytes", "write_text"]


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def atomic_write(path: str | os.PathLike, write: Callable[[str], object]) -> Path:
    """Call ``write(tmp_path)`` to create the file, then rename it to ``path``.

    Parameters
    ----------
    path : str or PathLike
        Target file; its folder must exist.
    write : callable
        Writes the whole file at the temporary path it is given (same folder and suffix as
        ``path``, so writers that pick a format from the suffix work).

    Returns
    -------
    Path
        ``path``.
    """
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    fd, tmp = tempfile.mkstemp(dir=folder, prefix=f".{path.stem}.", suffix=path.suffix)
    os.close(fd)
    _PENDING.add(tmp)
    try:
        write(tmp)
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    finally:
        _PENDING.discard(tmp)
    return path


#: temporary files of writes under way (removed by `remove_pending` when the process is
#: ended before they are renamed)
_PENDING: set[str] = set()


def remove_pending() -> None:
    """Remove the temporary files of the writes under way (for a process about to end
    without unwinding, as on SIGTERM)."""
    for tmp in list(_PENDING):
        try:
            os.unlink(tmp)
        except OSError:
            pass


def write_bytes(path: str | os.PathLike, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically."""
    return atomic_write(path, lambda tmp: Path(tmp).write_bytes(data))


def write_text(path: str | os.PathLike, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    return atomic_write(path, lambda tmp: Path(tmp).write_text(text, encoding="utf-8"))
