"""Gmsh mesh builders with physical groups for the boundary parts Gamma1, Gamma2, Gamma3."""
from .box import BoxMesh, build_box
from .rectangle import BOUNDARY_TAGS, SIDES, RectangleMesh, build_rectangle

__all__ = ["BOUNDARY_TAGS", "SIDES", "BoxMesh", "RectangleMesh", "build_box", "build_rectangle"]
