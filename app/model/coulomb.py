"""Coulomb friction on Gamma3 against the rigid foundation: the friction term of (3.4) is
theta_i psi(|u_tau|_delta) with psi(rho) = rho and the nodal factor

    theta_i = mu p_n,i (times theta(s_n) of the slip dependence, if any),

p_n,i the contact pressure at node i (normal compliance, memory term and the bound's
reaction: -sigma_nu of the bulk residual, as in contact.csv).  The bound mu p_n depends on
the solution: the step problem is quasi-variational.  ``CoulombPressure`` holds p_n and
measures it from the current u; the fixed point on p_n inside each step that alternates the
bound and the step solves is ``CoulombFixedPoint`` (app/solvers/coulomb.py), a step solver
around SNES VI or the condensed solver.
The static/kinetic law mu(s) = mu_s - (mu_s - mu_k) min(s_n / L, 1) is mu = mu_s times the
slip dependence theta(s_n) = 1 - (1 - mu_k / mu_s) min(s_n / L, 1)
(``contact_laws.StaticKineticSlip``, summed by the Gamma3 slip machinery).  p_n is part of
the state a checkpoint stores: a restarted step starts its fixed point where the
uninterrupted run's does.

The two variants of ``contact.friction.coulomb`` are declared here once, as the other
contact laws are (``ContactLawSpec``, app/model/contactspec.py; the registry ``COULOMBS`` of
app/model/contactregistry.py, chosen by the keys given): ``CONSTANT_MU`` (mu) and
``STATIC_KINETIC`` (mu_s, mu_k, slip_length).  A variant's ``build`` gives its
``CoulombLaw``: the coefficient mu of the bound mu p_n and its slip dependence theta(s_n).
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from vpcontact.io.errors import CaseError
from vpcontact.model.contact_laws import StaticKineticSlip
from vpcontact.model.contactspec import ContactKey, ContactLawSpec


class CoulombPressure:
    """The contact pressure p_n at the local Gamma3 nodes (owned and ghost), of the Coulomb
    bound mu p_n.

    Args:
        problem: the ContactProblem (u, the Gamma3 nodes, frames and weights).
        mu: the friction coefficient (mu_s of the static/kinetic law); with laws per pair,
            its value at each local Gamma3 node (0 at the nodes of pairs without Coulomb).
        field: a NodalField of the Gamma3 nodes (scratch: p_n's ghost values).
        hold: the ContactHold of a body held only by contact
            (app/model/semicoercive.py: each step's fixed point starts from the pressure of
            its normal load), or None.
    """

    hold = None

    def __init__(self, problem, mu: float, field, hold=None):
        self.problem, self.mu, self.field, self.hold = problem, mu, field, hold
        nodes = problem.disc.gamma3_local_nodes
        self.p = np.zeros(len(nodes))
        self.owned = np.searchsorted(nodes, problem.disc.gamma3.nodes)

    def measure(self) -> np.ndarray:
        """p_n = (-sigma_nu)^+ at the current u: minus the normal component of the bulk
        residual divided by the node's weight (0 where u_nu is prescribed); collective.

        Returns:
            p_n at the local Gamma3 nodes (owned and ghost), shape (m,).
        """
        p, gm, fr = self.problem, self.problem.disc.gamma3, self.problem.disc.frames
        pos = np.searchsorted(fr.nodes, gm.nodes)
        p.current_stress()
        r = p.boundary_layer.residual()[gm.nodes]      # the bulk residual (app/model/layer.py)
        pn = -np.einsum("ij,ij->i", r, fr.normal[pos]) / gm.weight
        local = np.zeros(len(self.p))
        local[self.owned] = np.where(fr.bounded[pos], np.maximum(pn, 0.0), 0.0)
        self.field.set(local)
        self.field.function.x.scatter_forward()
        return self.field.function.x.array[self.field.dofs].copy()

    def start_step(self) -> None:
        """Before a step's fixed point: a body held only by the contact starts from the
        pressure of the step's load (``ContactHold.pressure_start``); else p_n stays the
        previous step's; collective."""
        if self.hold is not None:
            self.p = self._spread(self.hold.pressure_start(self._loads(), self.p[self.owned]))

    def _loads(self) -> np.ndarray:
        """The step's owned nodal loads f_n, (owned nodes, d)."""
        p, d = self.problem, self.problem.disc.dim
        owned = p.disc.V.dofmap.index_map.size_local
        if p.load_vector is None:
            return np.zeros((owned, d))
        return p.load_vector.at_current_time().array_r.reshape(-1, d)[:owned]

    def _spread(self, owned: np.ndarray) -> np.ndarray:
        """p at the local Gamma3 nodes (owned and ghost) from its owned values."""
        local = np.zeros(len(self.p))
        local[self.owned] = owned
        self.field.set(local)
        self.field.function.x.scatter_forward()
        return self.field.function.x.array[self.field.dofs].copy()

    def state(self) -> dict:
        """Returns: {"p": a copy of p_n (m,)}."""
        return {"p": self.p.copy()}

    def load_state(self, state: dict | None) -> None:
        """Set p_n from ``state()`` or a checkpoint's copy of it (None: start from 0).

        Args:
            state: {"p": array (m,)} or None.
        """
        self.p = np.zeros(len(self.p)) if state is None else np.array(state["p"], dtype=float)


class CoulombLaw(NamedTuple):
    """A Coulomb variant's law: the bound mu theta(s_n) p_n; it describes itself as the
    other laws do (``name``, ``constants()``: summary.json's "laws", app/post/lawreport.py).

    Attributes:
        mu: the coefficient (mu_s of the static/kinetic law).
        slip: its slip dependence theta(s_n) (a StaticKineticSlip), or None.
        name: the law in words.
        units: (key, value, unit) of its constants, in the case file's order.
    """

    mu: float
    slip: StaticKineticSlip | None = None
    name: str = "Coulomb friction"
    units: tuple = ()

    def constants(self) -> dict:
        """Returns: {key: (value, unit)} of the variant's constants."""
        return {key: (value, unit) for key, value, unit in self.units}


def _nonnegative(c: dict, key: str, path: str, source: str) -> None:
    """A friction coefficient of contact.friction.coulomb is >= 0."""
    if c[key] < 0:
        raise CaseError(f"{source}: {path}.{key}: must be >= 0 (a friction coefficient), got "
                        f"{c[key]:g}")


def _check_constant(c: dict, path: str, source: str) -> None:
    """contact.friction.coulomb: mu >= 0."""
    _nonnegative(c, "mu", path, source)


def _check_static_kinetic(c: dict, path: str, source: str) -> None:
    """contact.friction.coulomb: mu_s >= mu_k >= 0, slip_length > 0."""
    _nonnegative(c, "mu_k", path, source)
    if c["mu_s"] < c["mu_k"]:
        raise CaseError(f"{source}: {path}.mu_s: must be >= mu_k = {c['mu_k']:g} (the static "
                        f"coefficient is the larger), got {c['mu_s']:g}")
    if c["slip_length"] <= 0:
        raise CaseError(f"{source}: {path}.slip_length: must be > 0 (the accumulated slip "
                        f"[m s] over which mu falls from mu_s to mu_k), got "
                        f"{c['slip_length']:g}")


CONSTANT_MU = ContactLawSpec(
    name="mu", formula="mu p_n",
    keys={"mu": ContactKey({"type": "number", "description": "the Coulomb friction coefficient "
                            "(dimensionless, >= 0): the friction bound is mu p_n, p_n the "
                            "contact pressure at the node [N/m^2] (compliance, memory and the "
                            "bound's reaction); times theta(s) with slip"})},
    build=lambda c: CoulombLaw(c["mu"], None, "Coulomb friction mu p_n |u_tau|_delta (p_n by a "
                               "fixed point)", (("mu", c["mu"], "-"),)),
    check=_check_constant,
    title="Coulomb friction mu p_n (mu = {mu:g})")

STATIC_KINETIC = ContactLawSpec(
    name="static/kinetic", formula="mu(s) = mu_s - (mu_s - mu_k) min(s / slip_length, 1)",
    keys={"mu_s": ContactKey({"type": "number", "description": "the static coefficient "
                              "(dimensionless, >= mu_k): the bound mu(s) p_n at s = 0 (instead "
                              "of mu; with mu_k and slip_length)"}),
          "mu_k": ContactKey({"type": "number", "description": "the kinetic coefficient "
                              "(dimensionless, 0 <= mu_k <= mu_s): mu(s) for s >= "
                              "slip_length"}),
          "slip_length": ContactKey({"type": "number", "description": "the accumulated slip "
                                     "s = int_0^t |u_tau| [m s] (> 0) over which mu(s) falls "
                                     "linearly from mu_s to mu_k"})},
    build=lambda c: CoulombLaw(
        c["mu_s"], StaticKineticSlip(c["mu_s"], c["mu_k"], c["slip_length"]),
        "Coulomb friction mu(s) p_n |u_tau|_delta, mu(s) = mu_s - (mu_s - mu_k) "
        "min(s/slip_length, 1) (p_n by a fixed point)",
        (("mu_s", c["mu_s"], "-"), ("mu_k", c["mu_k"], "-"),
         ("slip_length", c["slip_length"], "m s"))),
    check=_check_static_kinetic,
    title="Coulomb friction mu(s) p_n (mu_s = {mu_s:g}, mu_k = {mu_k:g} over slip length "
          "{slip_length:g} m s)")
