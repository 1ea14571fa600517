"""One reader for every project file (layouts, sessions, fit files, summaries, manifests).

JSON from a file is data from outside: Python's parser recurses once per nesting level
(100,000 brackets end in ``RecursionError``), turns any run of digits into an integer (a
5,000-digit number is a ``ValueError``, 2**64 an ``OverflowError`` wherever it becomes an
index) and accepts ``NaN`` and ``Infinity``. :func:`read_json` bounds all of these before
or while parsing and raises the caller's error class with the file's name, so a damaged or
hostile file is one clear message, never a traceback.
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import numpy as np

from meshfit.errors import InputError

__all__ = ["MAX_BYTES", "MAX_DEPTH", "MAX_INT_DIGITS", "read_json", "read_json_file"]

#: deepest nesting of arrays and objects (a layout file nests four levels)
MAX_DEPTH = 64
#: most digits of an integer read at all (its value must then lie in the int64 range)
MAX_INT_DIGITS = 40
#: largest project file read, bytes (a layout of a few million curve points fits)
MAX_BYTES = 1 << 30

_STRINGS = re.compile(r'"(?:[^"\\]|\\.)*"')


def read_json(text: str | bytes, *, source: str, error: type[Exception] = InputError) -> Any:
    """Parse ``text`` as JSON within `MAX_DEPTH` nesting levels and `MAX_INT_DIGITS`-digit
    integers (within the int64 range), without NaN or Infinity.

    Raises
    ------
    error (default :class:`meshfit.errors.InputError`)
        Naming ``source``: malformed JSON (line and column), nesting too deep, an integer
        too large, a non-finite number, text that is not UTF-8.
    """
    if isinstance(text, bytes):
        try:
            text = text.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise error(f"{source}: not UTF-8 text (byte {exc.start})") from None
    depth = _depth(text)
    if depth > MAX_DEPTH:
        raise error(f"{source}: nested {depth} levels deep (at most {MAX_DEPTH} are read)")
    try:
        return json.loads(text, parse_int=_int(source, error), parse_constant=_no(source, error))
    except json.JSONDecodeError as exc:
        raise error(
            f"{source}: malformed JSON at line {exc.lineno}, column {exc.colno}: {exc.msg}"
        ) from None
    except RecursionError:  # (bounded above; kept for a parser that recurses deeper)
        raise error(f"{source}: nested too deep") from None


def read_json_file(
    path: str | Path, *, error: type[Exception] = InputError, max_bytes: int = MAX_BYTES
) -> Any:
    """:func:`read_json` of a file, refused unread above ``max_bytes``."""
    p = Path(path)
    size = p.stat().st_size
    if size > max_bytes:
        raise error(f"{p}: {size} bytes, more than the {max_bytes} a project file may have")
    return read_json(p.read_bytes(), source=str(p), error=error)


def _depth(text: str) -> int:
    """Deepest bracket nesting outside strings (a malformed text may give any number: the
    parser then names its fault)."""
    bare = _STRINGS.sub('""', text).encode("utf-8", "replace")
    a = np.frombuffer(bare, dtype=np.uint8)
    step = np.isin(a, (ord("["), ord("{"))).astype(np.int64)
    step -= np.isin(a, (ord("]"), ord("}")))
    return int(np.cumsum(step).max()) if a.size else 0


def _int(source: str, error: type[Exception]):
    lo, hi = -(1 << 63), (1 << 63) - 1

    def parse(s: str) -> int:
        if len(s.lstrip("-")) > MAX_INT_DIGITS:
            raise error(f"{source}: an integer of {len(s.lstrip('-'))} digits")
        v = int(s)
        if not lo <= v <= hi:
            raise error(f"{source}: the integer {s} is outside the 64-bit range")
        return v

    return parse


def _no(source: str, error: type[Exception]):
    def parse(s: str) -> Any:
        raise error(f"{source}: {s} is not a number JSON allows")

    return parse
