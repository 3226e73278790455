"""mpirun -n 2 gives the same results as a serial run (summary norms to 1e-8 relative)."""
import csv
import json

import numpy as np
import pytest

from conftest import PAPER_CASE, run_cli

pytestmark = pytest.mark.mpi
KEYS = ("norm_u_V", "norm_sigma_Q", "norm_kappa_Y", "max_vm", "max_kappa")


def _run(tmp_path, nprocs, extra=()):
    out = tmp_path / f"np{nprocs}"
    proc = run_cli(["run", PAPER_CASE, "--out", out, "--quiet", *extra], nprocs=nprocs)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    summary = json.loads((out / "summary.json").read_text())
    rows = list(csv.DictReader(open(out / "contact.csv")))
    return summary, rows


@pytest.mark.parametrize("mesh", [[], ["--set", "mesh.kind=unstructured", "--set", "mesh.h=0.08"]],
                         ids=["structured", "unstructured"])
def test_serial_equals_two_ranks(tmp_path, mesh):
    s1, c1 = _run(tmp_path, 1, mesh)
    s2, c2 = _run(tmp_path, 2, mesh)
    assert s2["mpi_ranks"] == 2 and s1["mesh"] == s2["mesh"]
    for a, b in zip(s1["steps"], s2["steps"], strict=True):
        for key in KEYS:
            assert b[key] == pytest.approx(a[key], rel=1e-8, abs=1e-14), key
    assert len(c1) == len(c2)
    for col in ("x", "u_x", "u_y", "neg_sigma_nu", "neg_sigma_tau"):
        v1 = np.array([float(r[col]) for r in c1])
        v2 = np.array([float(r[col]) for r in c2])
        np.testing.assert_allclose(v2, v1, rtol=1e-8, atol=1e-12 * np.abs(v1).max())
    assert [r["state"] for r in c1] == [r["state"] for r in c2]
