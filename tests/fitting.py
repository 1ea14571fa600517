"""The fit into a folder, as the command line runs it, returning the summary."""

from meshfit.pipeline import fit


def run_fit(mesh, out, *, layout="auto", **kw) -> dict:
    """``meshfit.fit(mesh, layout, out=out, ...)``'s summary (what ``summary.json`` holds)."""
    return fit(mesh, layout, out=out, **kw).summary
