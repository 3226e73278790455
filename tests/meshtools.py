"""Test support: gmsh .msh files of the built-in structured meshes, rotated rigidly.

``write_rotated_square`` and ``write_rotated_box`` let a test run the paper's scene from a mesh
file whose cells are exactly those of ``build_rectangle`` / ``build_box`` (same triangles or
tetrahedra, vertices exactly on the grid (L / n) i before the rotation), in rotated
coordinates; the named physical groups are the sides (left bottom right top, front back in 3D)
and "body".  Rotating the file's vertices back gives the built-in mesh to round-off
(tests/unit/test_meshfile.py checks it).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np


def rotation_2d(angle_deg: float) -> np.ndarray:
    """The 2 x 2 counter-clockwise rotation by angle_deg degrees.

    Args:
        angle_deg: the angle in degrees.

    Returns:
        The rotation matrix R (x_rotated = R x).
    """
    a = np.radians(angle_deg)
    return np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])


def rotation_3d(angles_deg) -> np.ndarray:
    """The rotation by angles_deg[0] degrees about z followed by angles_deg[1] about x.

    Args:
        angles_deg: (angle about z, angle about x) in degrees.

    Returns:
        The 3 x 3 rotation matrix R = R_x R_z (x_rotated = R x).
    """
    az, ax = np.radians(angles_deg[0]), np.radians(angles_deg[1])
    Rz = np.array([[np.cos(az), -np.sin(az), 0.0], [np.sin(az), np.cos(az), 0.0],
                   [0.0, 0.0, 1.0]])
    Rx = np.array([[1.0, 0.0, 0.0], [0.0, np.cos(ax), -np.sin(ax)],
                   [0.0, np.sin(ax), np.cos(ax)]])
    return Rx @ Rz


def _write_moved(path, build, n: int, R: np.ndarray) -> Path:
    """Build a structured unit mesh with ``build`` (meshes' own gmsh model), put its nodes on
    the grid i / n, rotate them by R and write the .msh 4.1 with "body" named."""
    import gmsh

    from vpcontact.meshes.rectangle import DOMAIN_TAG

    path = Path(path)
    d = R.shape[0]
    gmsh.initialize(readConfigFiles=False)
    gmsh.option.setNumber("General.Terminal", 0)
    try:
        build()
        gmsh.model.setPhysicalName(d, DOMAIN_TAG, "body")
        tags, coords, _ = gmsh.model.mesh.getNodes()
        x = coords.reshape(-1, 3)
        step = 1.0 / n
        x[:, :d] = step * np.rint(x[:, :d] / step)          # as meshes.rectangle.snap_to_grid
        x[:, :d] = x[:, :d] @ R.T
        for tag, p in zip(tags, x, strict=True):
            gmsh.model.mesh.setNode(int(tag), list(p), [])
        gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
        gmsh.option.setNumber("Mesh.Binary", 0)
        gmsh.write(str(path))
    finally:
        gmsh.finalize()
    return path


def write_rotated_square(path, n: int, angle_deg: float, diagonal: str = "right") -> Path:
    """Write the structured n x n unit square of build_rectangle, rotated about the origin.

    Args:
        path: the .msh file to write (format 4.1, ASCII).
        n: squares per side.
        angle_deg: the counter-clockwise rotation in degrees.
        diagonal: "right" or "left", as build_rectangle's.

    Returns:
        The path written.
    """
    from vpcontact.meshes.rectangle import _gmsh_model

    return _write_moved(path, lambda: _gmsh_model(1.0, 1.0, n, None, diagonal), n,
                        rotation_2d(angle_deg))


def write_rotated_box(path, n: int, angles_deg) -> Path:
    """Write the structured n x n x n unit box of build_box (engine "gmsh"), rotated.

    Args:
        path: the .msh file to write (format 4.1, ASCII).
        n: cubes per side.
        angles_deg: (angle about z, angle about x) in degrees; see rotation_3d.

    Returns:
        The path written.
    """
    from vpcontact.meshes.box import _gmsh_model

    return _write_moved(path, lambda: _gmsh_model((1.0, 1.0, 1.0), n, None), n,
                        rotation_3d(angles_deg))
