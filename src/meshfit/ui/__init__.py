"""The interactive web app (``meshfit ui``): paint and edit patch-boundary curves in the browser.

:class:`Session` (``meshfit.ui.state``) is the controller: the mesh, painted corners and
curves, undo/redo and the autosave file, with one method per user action, each calling the
public meshfit API. :func:`network_status` tells which regions of a painted network are valid
four-sided patches and why the others are not. ``meshfit.ui.app.App`` is the thin viser layer
(imported on demand: it needs ``viser``), ``meshfit.ui.fitview`` draws a fit into its scene
and ``meshfit.ui.fitting`` holds what the app does with a fit (deviation from the scan in
percent of the diagonal, one-patch re-fits, the map brush); :class:`FilePolicy` and
:func:`mesh_from_upload` keep file access to the files the user names and validate uploads.

References
----------
.. [1] Krishnamurthy, "Fitting Smooth Surfaces to Dense Polygon Meshes", PhD thesis, Stanford
   2000, sec. 1.2.1 (a creative, interactive step with real-time feedback at every stage),
   sec. 3.8 (snake editing, colour attraction), sec. 5.7 and 5.13 (coarse-to-fine previews).
"""

from meshfit.ui.files import FilePolicy, mesh_from_upload
from meshfit.ui.network import NetworkStatus, RegionStatus, network_status
from meshfit.ui.picking import pick_point
from meshfit.ui.state import ColorAttraction, PaintedCurve, PatchFit, Session, SessionState, Stroke

__all__ = [
    "ColorAttraction",
    "FilePolicy",
    "NetworkStatus",
    "PaintedCurve",
    "PatchFit",
    "RegionStatus",
    "Session",
    "SessionState",
    "Stroke",
    "mesh_from_upload",
    "network_status",
    "pick_point",
]
