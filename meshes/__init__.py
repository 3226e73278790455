"""Meshes with named boundary groups: the built-in rectangle and box (gmsh or dolfinx) and the
user's own gmsh files (.msh, or .geo meshed at load time)."""
from .box import BoxMesh, build_box
from .gmshfile import FileMesh, MeshFileError, load_mesh_file
from .rectangle import BOUNDARY_TAGS, SIDES, RectangleMesh, build_rectangle

__all__ = ["BOUNDARY_TAGS", "SIDES", "BoxMesh", "FileMesh", "MeshFileError", "RectangleMesh",
           "build_box", "build_rectangle", "load_mesh_file"]
