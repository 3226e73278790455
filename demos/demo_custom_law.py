# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: light
#       format_version: '1.5'
# ---

# # A viscoplastic law of your own: hyperbolic-sine creep
#
# This demo (`demo_custom_law.py`) writes a viscoplastic law that vpcontact does not ship,
# Garofalo's hyperbolic-sine creep law, and runs the paper's example with it. It illustrates
# how to:
#
# - write a law in the user protocol of `app/model/laws.py`: a class with `m`, `G` and `Gk`,
#   vectorised over cells, in tensors;
# - pass it to a `Simulation` (`law=`), with the explicit and with the implicit scheme;
# - use the same file from the command line with `--law-module`.
#
# Run it from the repository root, serially or on two MPI ranks:
#
#     .venv/bin/python demos/demo_custom_law.py
#     mpirun -n 2 .venv/bin/python demos/demo_custom_law.py
#
# As in `demo_wang_cheng.py`, run it with `OPENBLAS_NUM_THREADS=1`.

# +
import logging
import sys
from pathlib import Path

import numpy as np
from mpi4py import MPI

from vpcontact import Simulation, validate
from vpcontact.case import load_raw

# -

# ## The law
#
# Creep without a yield surface, the strain rate a hyperbolic sine of the von Mises stress
# $\sigma_{eq} = \|\sigma\|_{VM}$:
#
# $$\dot\varepsilon^{vp} = A \sinh(\sigma_{eq}/s_0)\, N, \qquad
# N = \frac{3}{2}\frac{\operatorname{dev}\sigma}{\sigma_{eq}},$$
#
# so that, with $\kappa = p$ the accumulated creep strain ($m = 1$),
#
# $$\mathcal G(\sigma, \kappa) = -\mathcal E \dot\varepsilon^{vp}, \qquad
# G(\sigma, \kappa) = A \sinh(\sigma_{eq}/s_0).$$
#
# For small stresses it is Norton's law with $n = 1$, for large ones an exponential law.
# The class receives the case's elasticity $\mathcal E$ first (`app/model/material.py`:
# `Cmat`, `apply`, `to_voigt`, `from_voigt`), then its constants. `G` and `Gk` take numpy
# arrays over the cells: `sigma` and `eps` of shape (ncells, d, d) and `kappa` of shape
# (ncells, m), and return (ncells, d, d) and (ncells, m). The deviator is the 3D one with
# $\sigma_{33} = 0$: plane stress (the paper's) or 3D. This law does not need the strain
# `eps`; a law that does reads it there.


# +
class SinhCreep:
    """Hyperbolic-sine creep: eps_vp' = A sinh(sigma_eq / s0) N, G = -E eps_vp',
    Gk = A sinh(sigma_eq / s0), kappa = p (m = 1)."""

    m = 1
    name = "sinh creep"

    def __init__(self, elasticity, A, s0):
        self.elasticity, self.A, self.s0 = elasticity, A, s0

    def _rate_and_flow(self, sigma):
        """A sinh(sigma_eq / s0) and the flow direction N per cell."""
        d = sigma.shape[1]
        dev = sigma - np.einsum("nii->n", sigma)[:, None, None] / 3.0 * np.eye(d)
        # sigma_eq^2 = 3/2 dev:dev, with dev_33 = -tr/3 in plane stress
        extra = (np.einsum("nii->n", sigma) / 3.0) ** 2 if d == 2 else 0.0
        q = np.sqrt(1.5 * (np.einsum("nij,nij->n", dev, dev) + extra))
        rate = self.A * np.sinh(q / self.s0)
        # N = 3/2 dev / q; rate * N -> 3/2 A/s0 dev as q -> 0
        ratio = np.where(q > 0, rate / np.where(q > 0, q, 1.0), self.A / self.s0)
        return rate, 1.5 * ratio[:, None, None] * dev

    def G(self, sigma, eps, kappa):
        """G = -E eps_vp' (ncells, d, d)."""
        _, flow = self._rate_and_flow(sigma)
        el = self.elasticity
        return -el.from_voigt(el.apply(el.to_voigt(flow)))

    def Gk(self, sigma, eps, kappa):
        """Gk = p' = A sinh(sigma_eq / s0) (ncells, 1)."""
        rate, _ = self._rate_and_flow(sigma)
        return rate[:, None]


# -

# The law gives no `rate_bound()`: its relaxation rate grows without bound with the stress,
# so the explicit scheme's stability indicator is left out (a law that knows a bound
# returns it, and the run log shows $k\,r_{\max}$). Neither does it give its derivatives
# `dG`, `dGk`: the implicit scheme then takes a finite-difference Jacobian per cell.

if __name__ == "__main__":
    comm = MPI.COMM_WORLD
    log = logging.getLogger("vpcontact")
    handler = logging.StreamHandler(sys.stdout)
    handler.setFormatter(logging.Formatter("[vpcontact] %(message)s"))
    log.handlers[:] = [handler]
    log.setLevel(logging.WARNING if comm.rank == 0 else logging.CRITICAL)
    log.propagate = False

# ## The runs
#
# The paper's case on a coarse grid, $h = k = 1/8$. `Simulation(case, comm, law=...)` takes
# the class (or any callable that builds the law from the elasticity, such as the lambda
# below, or a law object already built); the law replaces the case's Perzyna law, and the
# case's `kappa0` is the initial $p$.

CASE_FILE = Path(__file__).resolve().parents[1] / "cases" / "wang_cheng_2021.yaml"
BASE = ["mesh.n=8", "time.N=8"]
A, S0 = 0.001, 5.0


def simulate(*changes: str):
    """Run the case with ``changes`` on top of BASE and the sinh creep law.

    Args:
        changes: more overrides, e.g. "time.scheme=implicit".

    Returns:
        The RunSummary.
    """
    case = validate(load_raw(CASE_FILE, [*BASE, *changes]), str(CASE_FILE))
    sim = Simulation(case, MPI.COMM_WORLD, law=lambda elasticity: SinhCreep(elasticity, A, S0))
    return sim.run()


if __name__ == "__main__":
    explicit = simulate()
    implicit = simulate("time.scheme=implicit")
    last_e, last_i = explicit.steps[-1], implicit.steps[-1]
    if comm.rank == 0:
        for name, s in (("explicit", last_e), ("implicit", last_i)):
            print(f"{name}: |u|_V = {s['norm_u_V']:.6g}, |sigma|_Q = {s['norm_sigma_Q']:.6g}, "
                  f"max p = {s['max_kappa']:.4g}")

# ## Checks
#
# Both runs completed; the creep strain $p$ grew in every step after the first (the
# explicit scheme's first step uses $\sigma_0 = 0$: no creep yet); the two schemes
# approximate the same solution, differing by the time discretisation error, $O(k)$, here
# at most 5 %.

if __name__ == "__main__":
    failures = []

    def check(ok: bool, what: str) -> None:
        """Record ``what`` as failed unless ``ok`` holds on every rank."""
        if not comm.allreduce(bool(ok), op=MPI.LAND):
            failures.append(what)

    check(explicit.status == implicit.status == "completed", "both runs completed")
    ps = [s["max_kappa"] for s in explicit.steps]
    check(all(b > a for a, b in zip(ps[1:], ps[2:])) and ps[1] > 0, "p grows in every step")
    for key in ("norm_u_V", "norm_sigma_Q", "max_kappa"):
        a, b = last_e[key], last_i[key]
        check(abs(a - b) <= 0.05 * abs(b), f"explicit and implicit agree ({key})")

# ## From the command line
#
# The same file is a law module for the command line: the case names the class and its
# constants, and `--law-module` gives the file (the run above is behind
# `if __name__ == "__main__"`, so importing the file only defines the class):
#
#     ./vpcontact run cases/wang_cheng_2021.yaml --law-module demos/demo_custom_law.py \
#         --set mesh.n=8 --set time.N=8 \
#         --set "material.viscoplastic={law: python, class: SinhCreep, params: {A: 0.001, s0: 5.0}}"
#
# computes the explicit run's norms at $t_N$:

if __name__ == "__main__":
    if comm.rank == 0:
        print(f"final norm_u_V = {last_e['norm_u_V']!r} "
              f"norm_sigma_Q = {last_e['norm_sigma_Q']!r}")
        print("checks:", "all passed" if not failures else "FAILED: " + "; ".join(failures))
    if failures:
        sys.exit(1)
