"""A results directory read for the figures: its files checked before any figure is drawn
(check_results) and the data the line figures draw (Results: mesh, last fields, contact
table, summary)."""
from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import NamedTuple

import numpy as np


class ResultsError(ValueError):
    """A file of a results directory is damaged or incomplete (the message names it)."""


def check_results(outdir: Path) -> None:
    """Check the files the figures read before any figure is drawn: summary.json is a JSON
    object, solution.xdmf and contact.xdmf are complete XML whose every HDF5 dataset exists
    in a readable solution.h5 / contact.h5 with the shape the XML states, contact.csv has
    whole rows of numbers (a damaged file made VTK abort the pictures' process, or ended
    in a matplotlib error naming no file).

    Args:
        outdir: the results directory.

    Raises:
        ResultsError: one line naming the file and what is wrong with it.
    """
    outdir = Path(outdir)
    path = outdir / "summary.json"
    try:
        summary = json.loads(path.read_text())
    except (ValueError, UnicodeDecodeError) as exc:
        raise ResultsError(f"{path}: not valid JSON ({exc}); the run's summary is damaged") \
            from None
    if not isinstance(summary, dict):
        raise ResultsError(f"{path}: not a run summary (a JSON object expected)")
    for stem in ("solution", "contact"):
        if stem == "solution" or (outdir / f"{stem}.xdmf").exists():
            _check_xdmf(outdir / f"{stem}.xdmf")
    _check_contact_csv(outdir / "contact.csv")


def _check_xdmf(path: Path) -> None:
    """An XDMF file parses and its HDF5 datasets exist with their stated shapes."""
    import xml.etree.ElementTree as ET
    try:
        items = [i for i in ET.parse(path).getroot().iter("DataItem")
                 if i.get("Format") == "HDF"]
    except (ET.ParseError, OSError) as exc:
        raise ResultsError(f"{path}: not a complete XDMF file ({exc})") from None
    files = {}
    try:
        for item in items:
            name, _, dataset = (item.text or "").strip().partition(":")
            _check_dataset(files, path, name, dataset, item.get("Dimensions", ""))
    finally:
        for f in files.values():
            f.close()


def _check_dataset(files: dict, path: Path, name: str, dataset: str, dims: str) -> None:
    """The dataset an XDMF DataItem names exists with its shape (files: open HDF5 files)."""
    import h5py
    h5 = path.parent / name
    try:
        if name not in files:
            files[name] = h5py.File(h5, "r")
        shape = tuple(int(n) for n in dims.split())
        found = files[name][dataset].shape if dataset in files[name] else None
    except (OSError, ValueError) as exc:
        raise ResultsError(f"{h5}: cannot be read ({exc})") from None
    if found != shape:
        raise ResultsError(f"{h5}: no dataset {dataset} of shape {shape} (named by "
                           f"{path.name}): the file is incomplete or damaged")


def _check_contact_csv(path: Path) -> None:
    """contact.csv (if there) has whole rows: a number in every column but state."""
    if not path.exists():
        return
    with open(path, newline="") as fh:
        for line, row in enumerate(csv.DictReader(fh), start=2):
            try:
                if None in row or None in row.values():
                    raise ValueError("a different number of columns than the header")
                [float(v) for k, v in row.items() if k != "state"]
            except ValueError as exc:
                raise ResultsError(f"{path}: line {line}: {exc}") from None


CONTACT_STATES = ("bound", "compliance")    # contact.csv's states of a node in contact


class ContactScene(NamedTuple):
    """What a run's contact boundary has at its last time (contact.csv).

    Attributes:
        boundary: the case has a contact boundary (Gamma3 or contact pairs): contact.csv
            has a row.
        forces: there are contact forces: a node of it in contact (state bound or
            compliance; a separated node has none, its -sigma_nu is rounding).
    """

    boundary: bool
    forces: bool


def contact_scene(outdir: Path) -> ContactScene:
    """The contact boundary and forces of a results directory (the contact figures are
    drawn for a scene that has them).

    Args:
        outdir: the results directory.

    Returns:
        The ContactScene of contact.csv (no file or no row: no boundary, no forces).
    """
    path = Path(outdir) / "contact.csv"
    if not path.exists():
        return ContactScene(False, False)
    with open(path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    return ContactScene(bool(rows), any(r["state"] in CONTACT_STATES for r in rows))


class Results:
    """The data of a results directory needed by the figures.

    Args:
        outdir: the results directory (solution.h5, contact.csv, summary.json).

    Attributes:
        summary: summary.json's data; ``case``: its case data.
        x, cells: the mesh's vertex coordinates and cells.
        fields: the last stored value of each field; ``t``: the time of u.
        contact: contact.csv's columns, or None.
    """

    def __init__(self, outdir: Path):
        self.dir = Path(outdir)
        self.summary = json.loads((self.dir / "summary.json").read_text())
        self.case = self.summary.get("case_data", {})
        self._read_fields()
        self.contact = self._read_contact()

    def _read_fields(self):
        import h5py
        with h5py.File(self.dir / "solution.h5", "r") as f:
            self.x = f["Mesh/mesh/geometry"][...]
            self.cells = f["Mesh/mesh/topology"][...].astype(np.int64)
            self.fields, self.times = {}, {}
            for name in f["Function"]:
                keys = list(f["Function"][name])
                last = max(keys, key=lambda k: float(k.replace("_", ".")))
                self.fields[name] = f["Function"][name][last][...]
                self.times[name] = float(last.replace("_", "."))
        self.dim = self.cells.shape[1] - 1
        self.x = self.x[:, :self.dim]
        self.t = self.times.get("u", 0.0)

    def _read_contact(self):
        path = self.dir / "contact.csv"
        if not path.exists():
            return None
        rows = list(csv.DictReader(open(path)))
        if not rows:
            return None
        out = {k: np.array([r[k] for r in rows]) for k in rows[0]}
        for k in out:
            if k != "state":
                out[k] = out[k].astype(float)
        return out

    @property
    def u(self) -> np.ndarray:
        """The displacement at the vertices, (vertices, d)."""
        return self.fields["u"][:, :self.dim]

    @property
    def pairs(self) -> list[dict]:
        """The case's contact pairs (two bodies: surface, target, ...), or []."""
        return list((self.case.get("contact") or {}).get("pairs") or [])

    def magnification(self) -> float:
        """The factor of the deformed views.

        Returns:
            1, 2 or 5 x 10^k making the largest displacement about 25% of the body size (1
            without displacement, and with contact pairs: two bodies drawn with a magnified
            displacement overlap where they approach each other).
        """
        if self.pairs:
            return 1.0
        size = float(np.ptp(self.x, axis=0).max())
        umax = float(np.abs(self.u).max())
        if umax <= 0:
            return 1.0
        return round_125(0.25 * size / umax)


def round_125(value: float) -> float:
    """The largest 1, 2 or 5 x 10^k not above a value (a round number for scales).

    Args:
        value: > 0.

    Returns:
        E.g. 0.05 for 0.073, 20 for 23.2.
    """
    decade = 10 ** np.floor(np.log10(value))
    return float(decade * np.array([1, 2, 5])[
        np.searchsorted([1, 2, 5], value / decade * (1 + 1e-12), side="right") - 1])
