"""The condensed solver's eligibility and the choice of method (app/solvers/choice.py), which
case validation imports: it must stay light (no dolfinx, no PETSc)."""
import subprocess
import sys

import pytest

from conftest import make_case
from vpcontact.solvers.choice import choose_method, condensed_eligible


def test_choice_imports_neither_dolfinx_nor_petsc():
    code = ("import sys, vpcontact.solvers.choice; "
            "print(sorted(m for m in ('dolfinx', 'petsc4py', 'ufl') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert out.strip() == "[]"


@pytest.mark.parametrize("sections, why", [
    ({}, ""),
    ({"time": {"scheme": "implicit"}}, "the implicit history variant makes the bulk problem "
                                       "nonlinear"),
    ({"solver": {"method": "snes_vi", "quadrature": "gauss"}},
     "the condensed solver needs the nodal (vertex) Gamma3 quadrature"),
])
def test_eligibility(sections, why):
    case = make_case(**sections)
    assert condensed_eligible(case) == (why == "", why)


def test_fast_is_the_condensed_solver():
    """``fast``, the former name, and ``condensed`` choose the same solver."""
    for method in ("fast", "condensed"):
        assert choose_method(make_case(solver={"method": method}), 10**6) == "condensed"
