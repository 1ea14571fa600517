"""Patch layouts: curve networks on a mesh, four-sided patches, and the layout file format."""

from meshfit.layout.patch import Patch

__all__ = ["Patch"]
