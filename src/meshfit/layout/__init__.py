"""Patch layouts: curve networks on a mesh, four-sided patches, and the layout file format."""

from meshfit.layout.cube import cube_layout
from meshfit.layout.extract import check_layout_topology, extract_patches
from meshfit.layout.io import layout_from_json, layout_to_json, load_layout, save_layout
from meshfit.layout.layout import Layout, check_layout, layout_from_curves, mesh_fingerprint
from meshfit.layout.patch import Patch
from meshfit.layout.smooth import curve_wiggle, smooth_layout

__all__ = [
    "Layout",
    "Patch",
    "check_layout",
    "check_layout_topology",
    "cube_layout",
    "curve_wiggle",
    "extract_patches",
    "layout_from_curves",
    "layout_from_json",
    "layout_to_json",
    "load_layout",
    "mesh_fingerprint",
    "save_layout",
    "smooth_layout",
]
