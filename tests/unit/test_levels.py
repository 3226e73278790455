"""GAMG's levels kept between Newton iterations and the finest level in the SBAIJ format
(app/solvers/levels.py), against PETSc's own AIJ product and GAMG's own re-set-up."""
import numpy as np
import pytest
import ufl
from dolfinx import fem, mesh
from dolfinx.fem.petsc import assemble_matrix
from mpi4py import MPI
from petsc4py import PETSc

from vpcontact.forms.elasticity import eps
from vpcontact.solvers.amg import near_nullspace, rigid_body_modes
from vpcontact.solvers.levels import GalerkinLevels, SymmetricCopy

pytestmark = pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="the SBAIJ copy is serial")


def _stiffness(n: int) -> tuple[PETSc.Mat, fem.FunctionSpace]:
    """The elasticity matrix of the unit cube (P1, n^3 cells), clamped on {x = 0}."""
    msh = mesh.create_unit_cube(MPI.COMM_SELF, n, n, n)
    V = fem.VectorFunctionSpace(msh, ("CG", 1))
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    a = fem.form((2.0 * ufl.inner(eps(u), eps(v)) + ufl.div(u) * ufl.div(v)) * ufl.dx)
    clamped = fem.locate_dofs_geometrical(V, lambda x: np.isclose(x[0], 0.0))
    bc = fem.dirichletbc(np.zeros(3), clamped, V)
    A = assemble_matrix(a, bcs=[bc])
    A.assemble()
    return A, V


def _bottom(V) -> np.ndarray:
    """The dofs of the nodes on {z = 0}."""
    bottom = fem.locate_dofs_geometrical(V, lambda x: np.isclose(x[2], 0.0))
    return (3 * bottom[:, None] + np.arange(3)).ravel().astype(PETSc.IntType)


def _change_bottom(A: PETSc.Mat, V, rng, scale: float = 1.0) -> PETSc.Mat:
    """A copy of A whose rows and columns of the dofs on {z = 0} change as contact terms
    do (a symmetric positive addition, ``scale`` times A's size) and some of whose dofs
    become identity rows."""
    B = A.copy()
    dofs = _bottom(V)
    values = scale * rng.uniform(0.5, 2.0, dofs.size)
    for i, d in enumerate(dofs):
        B.setValue(d, d, values[i], addv=True)
    B.assemble()
    B.zeroRowsColumns(dofs[2::3][::2], 1.0)       # some normal dofs active
    return B


def _cycle(pc: PETSc.PC, x: PETSc.Vec) -> np.ndarray:
    y = x.duplicate()
    pc.apply(x, y)
    return y.array.copy()


def _gamg(A: PETSc.Mat, V) -> PETSc.PC:
    A.setNearNullSpace(near_nullspace(rigid_body_modes(V), A))
    pc = PETSc.PC().create(MPI.COMM_SELF)
    opts = PETSc.Options("lv_")
    for key, value in {"pc_gamg_coarse_eq_limit": 60, "pc_gamg_agg_nsmooths": 0,
                       "pc_gamg_reuse_interpolation": True,
                       "mg_levels_ksp_type": "chebyshev", "mg_levels_pc_type": "jacobi",
                       "mg_levels_ksp_max_it": 2}.items():
        opts[key] = value
    pc.setOptionsPrefix("lv_")
    pc.setType("gamg")
    pc.setFromOptions()
    pc.setOperators(A, A)
    pc.setUp()
    return pc


def test_symmetric_copy_applies_the_aij_matrix():
    A, V = _stiffness(4)
    copy = SymmetricCopy(A)
    assert copy.mat.getType() == "seqsbaij" and copy.mat.getBlockSize() == 3
    x, y, z = A.createVecs() + (A.createVecLeft(),)
    x.setRandom()
    for M in (A, _change_bottom(A, V, np.random.default_rng(1))):
        copy.update(M)
        M.mult(x, y)
        copy.mat.mult(x, z)
        assert np.linalg.norm(z.array - y.array) <= 1e-14 * np.linalg.norm(y.array)


def test_symmetric_copy_refuses_a_pattern_without_whole_blocks():
    A = PETSc.Mat().createAIJ((6, 6), nnz=2, comm=MPI.COMM_SELF)
    A.setBlockSize(3)
    for i in range(6):
        A.setValue(i, i, 2.0)
    A.setValue(0, 5, 1.0)
    A.setValue(5, 0, 1.0)
    A.assemble()
    with pytest.raises(ValueError, match="whole blocks"):
        SymmetricCopy(A)


@pytest.mark.parametrize("sbaij, incremental", [(False, False), (True, False), (False, True),
                                                (True, True)])
def test_kept_levels_equal_gamgs_own_set_up(sbaij, incremental):
    """A V-cycle after GalerkinLevels.update (the finest level AIJ or its SBAIJ copy, the
    finest product in full or incremental) equals the one of a second GAMG that set itself
    up again (pc_gamg_reuse_interpolation) on the same changed matrix, twice in a row;
    without the update it differs."""
    A, V = _stiffness(6)
    mine, theirs = _gamg(A.copy(), V), _gamg(A.copy(), V)
    assert mine.getMGLevels() >= 3
    Jt = mine.getOperators()[1]
    copy = SymmetricCopy(Jt) if sbaij else None
    levels = GalerkinLevels(mine, copy.mat if sbaij else Jt,
                            _bottom(V) if incremental else None)
    assert (levels.product is not None) == incremental
    x = Jt.createVecLeft()
    x.setRandom()
    assert np.allclose(_cycle(mine, x), _cycle(theirs, x), rtol=1e-12, atol=0)
    for seed in (2, 3):
        changed = _change_bottom(A, V, np.random.default_rng(seed), scale=100.0)
        stale = _cycle(mine, x)
        for pc in (mine, theirs):
            changed.copy(pc.getOperators()[1], structure=PETSc.Mat.Structure.SAME_NONZERO_PATTERN)
        theirs.setUp()
        if sbaij:
            copy.update(Jt)
        levels.update(Jt)
        expected = _cycle(theirs, x)
        assert np.linalg.norm(stale - expected) > 1e-3 * np.linalg.norm(expected)
        assert np.linalg.norm(_cycle(mine, x) - expected) <= 1e-10 * np.linalg.norm(expected)


def test_incremental_product_refused_for_a_stiff_boundary():
    """Gamma3 terms 1e12 times the stiffness would leave their rounding error in C0: the
    finest product is formed in full (and the levels still equal GAMG's own)."""
    A, V = _stiffness(6)
    stiff = _change_bottom(A, V, np.random.default_rng(4), scale=1e12)
    mine = _gamg(stiff.copy(), V)
    levels = GalerkinLevels(mine, mine.getOperators()[1], _bottom(V))
    assert levels.product is None
