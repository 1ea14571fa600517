"""A small IGES 5.3 reader for the tests: sections, directory entries, entity 128."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from meshfit.bspline import BSplineSurface


def read_sections(path: Path) -> dict[str, list[str]]:
    """Records by section letter (column 73); checks record length and sequence numbers."""
    out: dict[str, list[str]] = {k: [] for k in "SGDPT"}
    for line in Path(path).read_text(encoding="ascii").splitlines():
        assert len(line) == 80, f"record of {len(line)} columns: {line!r}"
        letter, seq = line[72], int(line[73:80])
        out[letter].append(line)
        assert seq == len(out[letter]), f"section {letter} out of sequence at {seq}"
    return out


def _split_params(text: str) -> list[str]:
    """Free-format parameters: ',' between, ';' at the end; Hollerith strings kept whole."""
    toks, cur, i = [], "", 0
    while i < len(text):
        ch = text[i]
        if ch == "H" and cur.strip().isdigit():
            n = int(cur.strip())
            toks_str = text[i + 1 : i + 1 + n]
            cur = f"{n}H{toks_str}"
            i += 1 + n
            continue
        if ch in ",;":
            toks.append(cur.strip())
            cur = ""
            if ch == ";":
                break
        else:
            cur += ch
        i += 1
    return toks


def read_global(sections) -> list[str]:
    return _split_params("".join(line[:72] for line in sections["G"]))


def read_entities(path: Path) -> list[dict]:
    """Every directory entry with its parameter tokens."""
    sec = read_sections(path)
    term = sec["T"][0]
    counts = {term[k * 8]: int(term[k * 8 + 1 : k * 8 + 8]) for k in range(4)}
    assert counts == {k: len(sec[k]) for k in "SGDP"}, counts
    ents = []
    D, P = sec["D"], sec["P"]
    for k in range(0, len(D), 2):
        l1, l2 = D[k], D[k + 1]
        etype, pstart = int(l1[0:8]), int(l1[8:16])
        assert int(l2[0:8]) == etype
        nlines, form = int(l2[24:32]), int(l2[32:40])
        plines = P[pstart - 1 : pstart - 1 + nlines]
        assert all(int(p[64:72]) == k + 1 for p in plines), "P lines point at their DE"
        toks = _split_params("".join(p[:64] for p in plines))
        assert int(toks[0]) == etype
        ents.append({"type": etype, "form": form, "label": l2[56:64].strip(), "params": toks})
    return ents


def entity_128_surface(params: list[str]) -> BSplineSurface:
    """A polynomial, non-periodic entity 128 as a BSplineSurface (degree 3 only)."""
    f = [float(x.replace("D", "E")) for x in params[1:]]
    K1, K2, M1, M2 = (int(x) for x in f[:4])
    assert (M1, M2) == (3, 3)
    prop = [int(x) for x in f[4:9]]
    assert prop[2] == 1 and prop[3] == 0 and prop[4] == 0
    a = K1 + M1 + 2
    b = K2 + M2 + 2
    pos = 9
    ku = np.array(f[pos : pos + a])
    pos += a
    kv = np.array(f[pos : pos + b])
    pos += b
    n = (K1 + 1) * (K2 + 1)
    w = np.array(f[pos : pos + n])
    pos += n
    assert (w == 1).all()
    pts = np.array(f[pos : pos + 3 * n]).reshape(K2 + 1, K1 + 1, 3)  # u fastest
    pos += 3 * n
    urange, vrange = f[pos : pos + 2], f[pos + 2 : pos + 4]
    assert urange == [ku[0], ku[-1]] and vrange == [kv[0], kv[-1]]
    assert pos + 4 == len(f)
    return BSplineSurface(pts.transpose(1, 0, 2), ku, kv)
