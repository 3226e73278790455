"""Blow-up detection: growth that the model cannot produce stops a run as "diverged".

The exact solution of the model stays within a bound set by the data: the Perzyna law
relaxes the stress towards the yield set, and every force acting on the body is bounded by
the loads, the initial state and the contact laws.  An explicit history update beyond its
stability limit (k r_max > 2, see app/post/diagnostics.py) instead amplifies the overstress by
up to k r_max - 1 per step, so the norms grow geometrically and would reach 1e55 in a few
dozen steps while the run still "completes".

``stress_scale`` collects the data's stress levels (no solve needed):
- the loads and initial data: |f2| on the traction sides, |f0| L (div sigma = -f0),
  |sigma0| and E |u0| / L, sampled over the body and the time grid when the case was
  validated (Case.data_stress, app/case/datacheck.py);
- the contact laws: c_nu g (the normal compliance force at the bound), the memory force
  b0 T g, the friction bound's constants (each built-in contact law's ``levels``, its
  ContactLawSpec, app/model/contactspec.py);
- the elastic stress of a displacement g over the body, E_max g / L;
- the initial state as built: max ||sigma_0||_VM, and max kappa_0 for kappa's bound.
A step is diverged if a value is not finite, or if max ||sigma_n||_VM exceeds
BLOWUP_FACTOR (L / h) times that scale (L / h allows for stresses concentrated at corners
and on single contact nodes), or max kappa_n (its largest component, for m > 1) exceeds
kappa_0 plus the growth the law allows under that stress bound S, each built-in law's
``kappa_growth`` (its LawSpec, app/model/lawspec.py; app/model/lawregistry.kappa_growth):
2 T / (3 lambda2) S for Perzyna's (for the power law times r^(n-1), r = S / s_ref, when
r > 1); T A S^n for Norton's (kappa = p, p' = A sigma_eq^n); for Chaboche's the largest of S
(the back stress moves toward sigma - X, so ||X||_VM stays below sup ||sigma||_VM and each
component of X below that), |Q| (R moves from 0 toward Q) and T (2 S / K)^n (p' = <f/K>^n
with f <= ||sigma||_VM + ||X||_VM); none for a user's law.  The factor is generous: a run near
the explicit limit whose norms stay bounded is never stopped, and a genuinely exploding run
is stopped after a few steps.
"""
from __future__ import annotations

import logging
import math

from vpcontact.model.contactregistry import BOUNDS, KERNELS, NORMALS
from vpcontact.model.lawregistry import kappa_growth
from vpcontact.model.userlaw import UserLaw
from vpcontact.observers import Observer, StopRun
from vpcontact.post.quantities import cell_max
from vpcontact.records import HINT_DIVERGED, StepFailure

BLOWUP_FACTOR = 100.0
log = logging.getLogger("vpcontact")


def contact_scale(case, E_max: float, length: float, gap: float | None = None) -> float:
    """Stress levels of the contact laws: c_nu g, b0 T g, the friction constants, E g / L.

    Args:
        case: the validated Case.
        E_max: the largest eigenvalue of the elasticity tensor.
        length: the body's length scale L.
        gap: the largest gap on Gamma3 (default: contact.g, a number).

    Returns:
        The largest of these levels.
    """
    top = case.contact
    g = gap if gap is not None else (top.g if top.g is not None else 0.0)
    values = [E_max * g / length]
    r = g if top.g is not None else length
    for c in top.sections:          # the contact section, or each pair's laws
        values += _law_levels(c, case.time.T, r)
    return max(values)


def _law_levels(c, T: float, r: float) -> list[float]:
    """The stress levels of one set of contact laws (``contact_scale``) at the normal
    displacement r (the gap, or the length without one): each built-in law's ``levels``
    (its ContactLawSpec, app/model/contactregistry.py)."""
    values = []
    normal = NORMALS.get(getattr(c.normal, "law", None))     # a user's law: not known
    if normal is not None:          # c_nu r^m (a field c_nu(x): not known here), a table
        values += normal.levels(c.normal.constants, r)
    if c.memory is not None:
        b = abs(c.memory.b0 or 0.0) if not isinstance(c.memory.b0, str) else 0.0
        kernel = KERNELS[c.memory.kernel]
        if kernel.levels is not None:
            b = max([b, *kernel.levels(c.memory.constants)])
        values.append(b * T * r)
    if c.friction is not None and c.friction.law is not None:
        # a user's law: not known; Coulomb's bound mu p_n: of the normal laws' scale
        values += BOUNDS[c.friction.law].levels(c.friction.constants)
    return values


def stress_scale(case, problem) -> float:
    """The data's stress scale (see the module docstring); collective.

    Args:
        case: the validated Case (its data_stress from validation).
        problem: the ContactProblem (elasticity, length scale, initial sigma_vm).

    Returns:
        The scale (0 if the data has no stress at all).
    """
    E_max = problem.elasticity.bounds()[1]
    data = max(case.data_stress, contact_scale(case, E_max, problem.disc.length_scale,
                                               problem.disc.gap_scale))
    return max(data if math.isfinite(data) else 0.0, cell_max(problem, problem.sigma_vm))


class BlowUpMonitor(Observer):
    """Stops a run as "diverged" at the first step whose record leaves the bounds (see the
    module docstring): an observer whose ``check`` refuses the step, so the last good
    state is step n - 1.  The bounds are set when the run starts (``start``: from the
    initial or restarted state), or by ``set_bounds``."""

    def __init__(self):
        self.scale = self.bound = self.kappa_bound = None

    def set_bounds(self, case, problem, kappa0_max: float = 0.0) -> None:
        """The bounds of max ||sigma||_VM and max kappa (collective).

        Args:
            case: the validated Case.
            problem: the ContactProblem in its initial (or restarted) state.
            kappa0_max: max kappa of that state.
        """
        laws = [m.viscoplastic for m in case.all_materials if m.viscoplastic]   # materials
        self.scale = stress_scale(case, problem)
        h = problem.disc.body.h
        self.bound = BLOWUP_FACTOR * (problem.disc.length_scale / h) * self.scale
        self.kappa_bound = kappa0_max + max(
            (kappa_growth(vp, case.time.T, self.bound) for vp in laws), default=0.0)
        if isinstance(problem.law, UserLaw):      # a user's law (also one given in Python)
            self.kappa_bound = math.inf

    def start(self, sim) -> None:
        """Set the bounds from the run's state before its first step (collective).

        Args:
            sim: the Simulation, set up (its problem and kappa: the initial or restarted
                state).
        """
        p = sim.problem
        kappa = p.state.kappa
        self.set_bounds(sim.case, p, cell_max(p, kappa) if kappa is not None else 0.0)

    def check(self, sim, record: dict) -> None:
        """Refuse step n if its record is implausible (see ``blow_up``).

        Args:
            sim: the Simulation (sim.n, sim.t: the new step, not yet accepted).
            record: the step's record (app/records.py).

        Raises:
            StopRun: status "diverged", with what exceeded which bound.
        """
        why = self.blow_up(record)
        if why:
            log.error("step %d (t = %g) diverged: %s; stopping, the last good state is step %d",
                      sim.n, sim.t, why, sim.n - 1)
            raise StopRun("diverged", StepFailure(sim.n, sim.t, why, hint=HINT_DIVERGED))

    def blow_up(self, rec: dict) -> str | None:
        """What exceeded which bound in a step record.

        Args:
            rec: the step record (app/records.py).

        Returns:
            None if the step is plausible, else the reason.
        """
        bad = [key for key, v in rec.items() if isinstance(v, float) and not math.isfinite(v)]
        if bad:
            return f"non-finite values (NaN/Inf) in {', '.join(bad)}"
        if self.scale <= 0.0:           # no data at all: the solution is 0, nothing to bound
            return None
        if rec["max_vm"] > self.bound:
            return (f"max ||sigma||_VM = {rec['max_vm']:.3g} exceeds {self.bound:.3g}, "
                    f"{BLOWUP_FACTOR:g} (L/h) times the data's stress scale {self.scale:.3g}")
        if rec["max_kappa"] > self.kappa_bound:
            return (f"max kappa = {rec['max_kappa']:.3g} exceeds {self.kappa_bound:.3g}, the "
                    "growth the stress bound allows")
        return None
