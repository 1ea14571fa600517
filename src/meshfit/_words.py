"""Counted nouns for messages (private)."""

from __future__ import annotations


def plural(n: int, word: str) -> str:
    """``n`` and ``word``, plural unless ``n`` is 1 (the last word inflected: "patch" ->
    "patches", "non-manifold vertex" -> "non-manifold vertices", "face" -> "faces")."""
    if n == 1:
        return f"1 {word}"
    if word.endswith("vertex"):
        return f"{n} {word[:-2]}ices"
    if word.endswith(("ch", "sh", "s", "x")):
        return f"{n} {word}es"
    return f"{n} {word}s"
