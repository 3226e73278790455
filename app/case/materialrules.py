"""The rules of ``materials`` (one material per physical group of cells of a mesh.file) on
the data as given: either ``material`` or ``materials``; ``materials`` only with mesh.file;
one plane model for all groups.  Every rule of ``material`` applies to each entry of
``materials`` (``material_sections`` lists them, ``renamed`` makes a message of ``material``
name the entry's key path).  That the groups exist and cover the body is checked when the
mesh is loaded (app/model/materials.py).
"""
from __future__ import annotations

import re
from contextlib import contextmanager

from vpcontact.io.errors import CaseError


def check_material_keys(data: dict, source: str) -> None:
    """Either ``material`` or ``materials``; ``materials`` only with a mesh.file.

    Args:
        data: the case mapping as given (after the schema's check).
        source: the case file, for messages.

    Raises:
        CaseError: both keys, neither, or materials with the built-in mesh.
    """
    given = [k for k in ("material", "materials") if k in data]
    if len(given) == 2:
        raise CaseError(f"{source}: materials: give either material (one material for the "
                        "body) or materials (one per physical group of cells), not both")
    if not given:
        raise CaseError(f"{source}: (top level): 'material' is a required property (or "
                        "materials: one material per physical group of cells of a mesh.file)")
    if given == ["materials"] and "file" not in data["mesh"]:
        raise CaseError(f"{source}: materials: only with mesh.file (its physical groups of "
                        "cells name the materials' parts); the built-in mesh takes material")


def material_sections(data: dict) -> list[tuple[str, dict]]:
    """The material sections of a case and their key paths.

    Args:
        data: the case mapping.

    Returns:
        [("material", section)] or [("materials.<group>", section), ...] in the given order.
    """
    if "materials" in data:
        return [(f"materials.{group}", m) for group, m in data["materials"].items()]
    return [("material", data["material"])]


def renamed(message: str, path: str, section: str = "material") -> str:
    """A message of the rules of ``section`` naming the section at ``path`` instead.

    Args:
        message: the message (its key paths begin with ``section``).
        path: the section's key path, e.g. "materials.steel" (or "contact.pairs[1]" for
            the section "contact").
        section: the section the rules name.

    Returns:
        The message with its key paths ``section.``/``section:`` (at its start, after
        ": " or "(") starting with ``path``.
    """
    if path == section:
        return message
    return re.sub(rf"(^|: |\(){section}(?=[.:])", lambda mt: mt.group(1) + path, message)


@contextmanager
def section_errors(path: str, *errors: type, section: str = "material"):
    """Raise the CaseError (or one of ``errors``) of the block with ``renamed`` messages.

    Args:
        path: the section's key path.
        errors: further exception classes (one-argument messages) to rename.
        section: the section the block's messages name ("material" or "contact").

    Yields:
        None.
    """
    try:
        yield
    except (CaseError, *errors) as exc:
        raise type(exc)(renamed(str(exc), path, section)) from None


def check_planes(data: dict, source: str) -> None:
    """The groups of ``materials`` share one 2D model (plane stress or plane strain).

    Args:
        data: the default-filled case mapping.
        source: the case file, for messages.

    Raises:
        CaseError: two groups with different material.plane.
    """
    planes = {path: m.get("plane") for path, m in material_sections(data)}
    if len(set(planes.values())) > 1:
        shown = ", ".join(f"{path}.plane: {p}" for path, p in planes.items())
        raise CaseError(f"{source}: materials: the groups must have one 2D model ({shown}); "
                        "give every group the same plane")
