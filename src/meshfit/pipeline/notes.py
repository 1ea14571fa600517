"""The summary's notes: what a user should know about the input and the result."""

from __future__ import annotations

import numpy as np

from meshfit._words import plural
from meshfit.mesh import Mesh

#: components below this share of the area are named in the notes
SMALL_COMPONENT = 0.01


def small_components(mesh: Mesh, drop_below: float, notes: list[str]) -> Mesh:
    """The mesh, without its components below ``drop_below`` of the area when that is above
    0; components below `SMALL_COMPONENT` are named in ``notes`` either way."""
    from meshfit.mesh.components import component_shares, drop_small_components

    if mesh.n_components < 2:
        return mesh
    shares = component_shares(mesh)
    small = np.flatnonzero(shares < max(SMALL_COMPONENT, drop_below))
    if small.size == 0:
        return mesh
    worst = ", ".join(f"{100 * shares[c]:.2g}%" for c in small[np.argsort(shares[small])][:5])
    if drop_below > 0.0:
        mesh, _ = drop_small_components(mesh, drop_below)
        notes.append(
            f"dropped {plural(small.size, 'component')} below {100 * drop_below:.3g}% of the "
            f"area ({worst}; FitOptions.drop_components_below, --drop-components)"
        )
    else:
        notes.append(
            f"{plural(small.size, 'component')} below {100 * SMALL_COMPONENT:.3g}% of the area "
            f"({worst}), each laid out and fitted on its own: --drop-components SHARE "
            "(FitOptions.drop_components_below) drops them"
        )
    return mesh


#: a patch whose input vertices lie this far (fraction of the bbox diagonal) from the
#: displaced surface gets a note in the summary: the Hausdorff bound the fit is held to
FAR_INPUT = 0.005


def quality_notes(rows: list[dict], auto_seed: int | None = None) -> list[str]:
    """Warnings about patches whose spring mesh cannot be trusted; with ``auto_seed`` (the
    layout is automatic, from that base rotation), where the layout's patches are flagged,
    how to ask for another rotation."""
    from meshfit.layout.patch import patch_notes

    notes = []
    far = {
        r["patch"]: r["input_distance_max"]
        for r in rows
        if (r.get("input_distance_max") or 0.0) > FAR_INPUT
    }
    if far:
        worst = sorted(far.items(), key=lambda kv: -kv[1])[:5]
        notes.append(
            f"input vertices up to {100 * max(far.values()):.3g}% of the bbox diagonal from the "
            f"displaced surface in {len(far)} patches "
            f"({', '.join(f'patch {p}: {100 * v:.3g}%' for p, v in worst)}): the spring "
            "mesh does not reach part of the patch (a protrusion or pleat inside it): give a "
            "layout file with corners along that feature, or try more patches"
        )
    collapsed = [r["patch"] for r in rows if not np.isfinite(r.get("area_ratio", 1.0))]
    if collapsed:
        notes.append(
            f"spring meshes with collapsed (zero-area) cells in patches {collapsed}: their "
            "fit does not cover the whole patch; split those patches in the layout"
        )
    layout = patch_notes(rows)
    notes.extend(layout)
    if layout and auto_seed is not None:
        from meshfit.layout.auto import SEED_TRIES

        notes.append(
            f"the automatic layout starts from rotation {auto_seed} of its base mesh (the "
            f"next {SEED_TRIES - 1} are tried where its curves cross or a patch is a sliver): "
            "another start (--layout-seed N, FitOptions.layout_seed) gives other patches"
        )
    finer = {r["patch"]: r["finer"] for r in rows if r.get("finer", 0)}
    if finer:
        which = ", ".join(f"patch {p}: {plural(k, 'level')}" for p, k in finer.items())
        notes.append(
            "spring meshes made finer than the patch's vertex count to reach a protrusion or "
            f"pleat inside it ({which}): their displacement maps are larger"
        )
    folded = {r["patch"]: r["folded"] for r in rows if r.get("folded", 0)}
    if folded:
        worst = sorted(folded.items(), key=lambda kv: -kv[1])[:5]
        notes.append(
            f"{plural(sum(folded.values()), 'folded spring-mesh cell')} in "
            f"{plural(len(folded), 'patch')} "
            f"(most: {', '.join(f'patch {p}: {n}' for p, n in worst)})"
        )
    return notes
