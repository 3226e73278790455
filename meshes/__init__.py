"""Gmsh mesh builders with physical groups for the boundary parts Gamma1, Gamma2, Gamma3."""
from .rectangle import BOUNDARY_TAGS, RectangleMesh, build_rectangle

__all__ = ["BOUNDARY_TAGS", "RectangleMesh", "build_rectangle"]
