"""The compiled kernels (app/kernels/) equal their numpy references: the Perzyna
update, the cell passes, the split solve's sweeps, CHOLMOD's factor; the build reads the cdef
from the headers, hashes every file, and falls back to numpy where nothing can be built."""
import re
from pathlib import Path

import numpy as np
import pytest

from vpcontact import kernels
from vpcontact.kernels import build
from vpcontact.model.laws import ExplicitUpdate
from vpcontact.model.material import (
    FLAT,
    FROM,
    Elasticity,
    VonMisesProjection,
    from_voigt,
    to_voigt,
)
from vpcontact.model.viscoplastic import Perzyna
from vpcontact.solvers import dense, ldl, mumps

ROOT = Path(__file__).resolve().parents[2]
module = kernels.load()
needs_c = pytest.mark.skipif(module is None, reason="no C compiler")


def _reference(law, sigma, H, kappa, k, l1, l2):
    """The law's numpy update (app/model/viscoplastic.py)."""
    H, kappa = H.copy(), kappa.copy()
    ExplicitUpdate(Perzyna(law, l1, l2))(sigma, H, kappa.reshape(-1, 1), k)
    return H, kappa


def _kernel(law, l1, l2, **kw):
    """The compiled update with the law's data passed in."""
    return kernels.PerzynaKernel(law, VonMisesProjection(law), l1, l2, module, FLAT[law.dim],
                                 FROM[law.dim], **kw)


@needs_c
@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("dim", [2, 3])
def test_kernel_equals_numpy(dim, threads, monkeypatch):
    rng = np.random.default_rng(dim)
    law = Elasticity(1000.0, 0.4 if dim == 2 else 0.3, dim)
    n = 4000
    t = rng.normal(size=(n, law.m)) * 10.0 ** rng.uniform(-3, 3, size=(n, 1))
    t[:5] = 0.0                                         # zero stress
    t[5:10] *= 1e150                                    # |s|^2 would overflow
    sigma = from_voigt(t, dim).reshape(-1).copy()
    vm = law.von_mises(t)
    kappa = vm * rng.uniform(0.0, 2.0, size=n)          # about half inside, half outside
    kappa[10:20] = 0.0                                  # projection onto {0} (3D: hydrostatic)
    kappa[20:25] = vm[20:25]                            # on the boundary
    H0 = rng.normal(size=n * dim * dim)
    H0 = from_voigt(to_voigt(H0, dim), dim).reshape(-1).copy()   # symmetric
    H_ref, kappa_ref = _reference(law, sigma, H0, kappa, 0.01, 100.0, 50.0)
    monkeypatch.setattr(kernels.cells, "SPLIT_MIN_CELLS", 0)
    kern = _kernel(law, 100.0, 50.0)
    H, kap = H0.copy(), kappa.copy()
    assert kern.advance(sigma, H, kap, 0.01, threads) == 0
    if threads == 2:                        # each cell alone: one thread's results exactly
        H1, kap1 = H0.copy(), kappa.copy()
        assert _kernel(law, 100.0, 50.0).advance(sigma, H1, kap1, 0.01, 1) == 0
        assert np.array_equal(H, H1) and np.array_equal(kap, kap1)
    # round-off of the excess t - P t is relative to |t|: the update's scale k/(2 l1) E |t|
    scale = np.abs(H0).reshape(n, -1).max(axis=1) + 0.01 / 200.0 * 1000.0 * np.abs(t).max(axis=1)
    err = np.abs(H - H_ref).reshape(n, -1).max(axis=1) / scale
    assert err.max() <= 1e-12
    assert np.allclose(kap, kappa_ref, rtol=1e-12, atol=0.0)
    inside = law.von_mises(t) < kappa * (1 - 1e-12)
    assert np.array_equal(H.reshape(n, -1)[inside], H0.reshape(n, -1)[inside])   # no flow


@needs_c
def test_kernel_propagates_nan():
    law = Elasticity(1000.0, 0.4, 2)
    t = np.array([[1.0, 2.0, np.nan], [3.0, 0.0, 1.0]])
    sigma = from_voigt(t, 2).reshape(-1).copy()
    H, kappa = np.zeros(8), np.array([0.1, 0.1])
    _kernel(law, 1.0, 1.0).advance(
        sigma, H, kappa, 0.1)
    assert np.isnan(H[:4]).all() and np.isnan(kappa[0])
    assert np.isfinite(H[4:]).all() and np.isfinite(kappa[1])


@needs_c
def test_kernel_checks_arrays():
    law = Elasticity(1000.0, 0.4, 2)
    kern = _kernel(law, 1.0, 1.0)
    with pytest.raises(ValueError):
        kern.advance(np.zeros(8), np.zeros(8), np.zeros(3), 0.1)
    with pytest.raises(TypeError):
        kern.advance(np.zeros(8, dtype=np.float32), np.zeros(8), np.zeros(2), 0.1)


@needs_c
@pytest.mark.parametrize("factor", [1.0, 1e3, 1e-3])
def test_kernel_start_from_last_roots(factor):
    """Each cell's root search starts from its root of the last call (PerzynaKernel.mu); a
    start above or below the root gives the same update as the cold start."""
    rng = np.random.default_rng(7)
    law = Elasticity(1000.0, 0.4, 2)
    t = rng.normal(size=(500, law.m))
    sigma = from_voigt(t, 2).reshape(-1).copy()
    kappa0 = law.von_mises(t) * rng.uniform(0.1, 0.9, size=500)     # all outside
    kern = _kernel(law, 100.0, 50.0)
    H1, k1 = np.zeros(2000), kappa0.copy()
    assert kern.advance(sigma, H1, k1, 0.01) == 0                   # cold: mu = 0 on entry
    assert np.all(kern.mu > 0)
    kern.mu *= factor
    H2, k2 = np.zeros(2000), kappa0.copy()
    assert kern.advance(sigma, H2, k2, 0.01) == 0
    assert np.abs(H2 - H1).max() <= 1e-13 * np.abs(H1).max()
    assert np.abs(k2 - k1).max() <= 1e-13 * np.abs(k1).max()


@needs_c
def test_kernel_failure_writes_nothing():
    """If a cell's root search does not converge (here: one sweep allowed), the kernel says
    so and leaves H and kappa as they were (the history keeps step n - 1)."""
    rng = np.random.default_rng(3)
    law = Elasticity(1000.0, 0.4, 2)
    t = rng.normal(size=(50, law.m))
    sigma = from_voigt(t, 2).reshape(-1).copy()
    kappa = law.von_mises(t) * 0.5
    H = rng.normal(size=200)
    H0, kappa0 = H.copy(), kappa.copy()
    kern = _kernel(law, 1.0, 1.0, max_iter=1)
    assert kern.advance(sigma, H, kappa, 0.1) > 0
    assert np.array_equal(H, H0) and np.array_equal(kappa, kappa0)


@needs_c
def test_two_threads_write_nothing_if_one_half_fails(monkeypatch):
    """The first half of the cells converges at once (started from its roots), the second
    does not within one sweep: neither half is written."""
    monkeypatch.setattr(kernels.cells, "SPLIT_MIN_CELLS", 0)
    rng = np.random.default_rng(4)
    law = Elasticity(1000.0, 0.4, 2)
    t = rng.normal(size=(60, law.m))
    sigma = from_voigt(t, 2).reshape(-1).copy()
    kappa = law.von_mises(t) * 0.5                  # all outside
    kern = _kernel(law, 1.0, 1.0)
    assert kern.advance(sigma, np.zeros(240), kappa.copy(), 0.1, 2) == 0   # the roots
    kern.max_iter = 1
    sigma[120:] *= 3.0                              # the second half's roots move
    H, kap = rng.normal(size=240), kappa.copy()
    H0 = H.copy()
    assert kern.advance(sigma, H, kap, 0.1, 2) > 0
    assert np.array_equal(H, H0) and np.array_equal(kap, kappa)
    kern.max_iter = 100                             # and with them all: both halves move
    assert kern.advance(sigma, H, kap, 0.1, 2) == 0
    assert not np.array_equal(H[:120], H0[:120]) and not np.array_equal(H[120:], H0[120:])


# ------------------------------------------------------------------ cell passes
def _cells(dim, n_cells=300, n_nodes=120, seed=0):
    rng = np.random.default_rng(seed)
    nodes = np.array([rng.choice(n_nodes, dim + 1, replace=False) for _ in range(n_cells)],
                     dtype=np.intc)
    G = rng.normal(size=(n_cells, dim + 1, dim))
    vol = rng.uniform(0.5, 2.0, size=n_cells)
    u = rng.normal(size=n_nodes * dim)
    H = rng.normal(size=n_cells * dim * dim)
    return nodes, G, vol, u, H


@needs_c
@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("with_H", [False, True])
def test_cell_pass_equals_numpy(dim, with_H, threads, monkeypatch):
    """cell_pass: the same sums, sigma and von Mises norm as the numpy reference (sums in
    another order: 1e-13 relative); on two threads sigma and vm exactly those of one."""
    monkeypatch.setattr(kernels.cells, "SPLIT_MIN_CELLS", 0)
    nodes, G, vol, u, H = _cells(dim, seed=dim)
    H = H if with_H else None
    n = len(nodes)
    out = [(np.empty(n * dim * dim), np.empty(n)) for _ in range(3)]
    e2, s2 = kernels.cell_pass(module, nodes, G, vol, 0.7, 1.3, u, H, *out[0], threads=threads)
    kernels.cell_pass(module, nodes, G, vol, 0.7, 1.3, u, H, *out[2], threads=1)
    assert all(np.array_equal(a, b) for a, b in zip(out[0], out[2]))
    e2r, s2r = kernels.cell_pass_numpy(nodes, G, vol, 0.7, 1.3, u, H, *out[1])
    assert e2 == pytest.approx(e2r, rel=1e-13) and s2 == pytest.approx(s2r, rel=1e-13)
    for a, b in zip(out[0], out[1]):
        assert np.abs(a - b).max() <= 1e-13 * np.abs(b).max()
    e2_only = kernels.cell_pass(module, nodes, G, vol, 0.7, 1.3, u)
    assert e2_only == (pytest.approx(e2r, rel=1e-13), 0.0)
    assert kernels.cell_pass_numpy(nodes, G, vol, 0.7, 1.3, u)[1] == 0.0


@needs_c
@pytest.mark.parametrize("dim", [2, 3])
def test_cell_load_equals_numpy(dim):
    nodes, G, vol, u, H = _cells(dim, seed=10 + dim)
    b, bref = np.ones(len(u)), np.ones(len(u))
    kernels.cell_load(module, nodes, G, H, b)
    kernels.cell_load_numpy(nodes, G, H, bref)
    assert np.abs(b - bref).max() <= 1e-13 * np.abs(bref).max()


# ------------------------------------------------------------------ split solve, CHOLMOD
def _spd(n, seed):
    rng = np.random.default_rng(seed)
    B = rng.normal(size=(n, n)) * (rng.random((n, n)) < 0.1)
    return B @ B.T + n * np.eye(n)


@needs_c
@pytest.mark.parametrize("kind", ["superlu", "cholmod"])
@pytest.mark.parametrize("bs", [1, 2])
def test_split_solve_equals_numpy(kind, bs):
    """GLastSolve's forward and backward sweeps against split_solve_numpy with numpy's L D L^T
    (ldl_numpy) in the same order: different factorisations of a well-conditioned matrix,
    equal to 1e-12."""
    import scipy.sparse as sp

    from vpcontact.solvers.schur import CSR, GLastLDL, GLastLU
    A = _spd(40, seed=bs)
    G = np.array([6, 7, 30, 31])
    S = sp.csr_matrix(A)
    csr = CSR(S.indptr, S.indices, S.data)
    if kind == "cholmod":
        if ldl.load() is None:
            pytest.skip("CHOLMOD not available")
        f = GLastLDL(csr, G, bs, ldl.load())
    else:
        f = GLastLU(csr, G, bs)
    split = kernels.GLastSolve(f, module, bs)
    L, D = ldl.ldl_numpy(A, f.perm)
    rng = np.random.default_rng(4)
    b, y = rng.normal(size=40), rng.normal(size=4)
    r = split.forward(b).copy()
    u = np.empty(40)
    split.backward(y, u)
    r_ref, u_ref = kernels.split_solve_numpy(L, D, f.perm, 4, b, y)
    assert np.abs(r - r_ref).max() <= 1e-12 * np.abs(r_ref).max()
    assert np.abs(u - u_ref).max() <= 1e-12 * np.abs(u_ref).max()
    assert kernels.split_solve_numpy(L, D, f.perm, 4, b)[1] is None


def _grid_laplacian(k: int, bs: int):
    """The 5-point Laplacian of a k x k grid plus the identity, each node bs dofs (CSR)."""
    import scipy.sparse as sp
    T = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(k, k))
    A = sp.kron(T, sp.eye(k)) + sp.kron(sp.eye(k), T) + sp.eye(k * k)
    return sp.csr_matrix(sp.kron(A, np.eye(bs) + 0.1 * (1 - np.eye(bs))))


@pytest.mark.parametrize("seed", range(4))
def test_cell_components_partition_as_scipy(seed):
    """The union-find gives scipy's partition of the nodes (labels may differ), numbered by
    their lowest nodes; isolated nodes are parts of their own."""
    from vpcontact.model.dirichlet import components_scipy
    mod = kernels.load()
    if mod is None:
        pytest.skip("no compiled kernels")
    rng = np.random.default_rng(seed)
    n, nv = 400, 3
    cells = rng.integers(0, n, size=(60 + 40 * seed, nv)).astype(np.intc)
    label = np.empty(n, dtype=np.intc)
    count = mod.lib.cell_components(n, len(cells), nv, kernels.buf(mod.ffi, cells),
                                    kernels.buf(mod.ffi, label))
    ref = components_scipy(n, cells)
    assert count == ref.max() + 1 == label.max() + 1
    pairs = set(zip(label.tolist(), ref.tolist()))
    assert len(pairs) == count                      # one scipy part per label, and back
    first = [int(np.flatnonzero(label == k)[0]) for k in range(count)]
    assert first == sorted(first)                   # numbered by their lowest node
    assert all(np.all(label[c] == label[c[0]]) for c in cells)


def test_subtree_split_of_small_trees():
    """Two chains under a common top are swept at once; a single chain is not split."""
    from vpcontact.kernels.sweeps import subtree_split
    # columns 0 -> 1 -> 4 and 2 -> 3 -> 4, 4 -> row 5 (G); Bi the rows below the diagonal
    Bp, Bi = np.array([0, 2, 3, 5, 6, 7]), np.array([1, 4, 4, 3, 4, 4, 5])
    assert subtree_split(Bp, Bi, 5) == (2, 4)
    Bp, Bi = np.array([0, 1, 2, 3, 4]), np.array([1, 2, 3, 4])        # 0 -> 1 -> 2 -> 3
    assert subtree_split(Bp, Bi, 4) is None


@needs_c
@pytest.mark.parametrize("bs", [1, 2])
def test_two_thread_sweeps_equal_one_thread_and_numpy(bs, monkeypatch):
    """GLastSolve with two threads (the parts of subtree_split swept at once) equals the
    one-thread sweeps to round-off and split_solve_numpy to 1e-12, on a grid Laplacian
    ordered by CHOLMOD's nested dissection with one side of the grid as Gamma3."""
    from vpcontact.kernels import sweeps
    from vpcontact.solvers.schur import CSR, GLastLDL
    if ldl.load() is None:
        pytest.skip("CHOLMOD not available")
    monkeypatch.setattr(sweeps, "SPLIT_MIN_BLOCKS", 0)
    k = 24
    S = _grid_laplacian(k, bs)
    G = (bs * np.arange(k)[:, None] + np.arange(bs)).ravel()          # the grid's row 0
    f = GLastLDL(CSR(S.indptr, S.indices, S.data), G, bs, ldl.load())
    one, two = (kernels.GLastSolve(f, module, bs, threads=t) for t in (1, 2))
    assert one.split is None and two.split is not None
    s1, s2 = two.split
    assert 0 < s1 < s2 <= two.nbc
    rng = np.random.default_rng(5)
    n, m = S.shape[0], len(G)
    b, y = rng.normal(size=n), rng.normal(size=m)
    out = {}
    for name, solve in (("one", one), ("two", two)):
        r = solve.forward(b).copy()
        u = np.empty(n)
        solve.backward(y, u)
        out[name] = r, u
    for a, c in zip(out["one"], out["two"]):
        assert np.abs(a - c).max() <= 1e-14 * np.abs(a).max()
    L, D = ldl.ldl_numpy(S.toarray(), f.perm)
    r_ref, u_ref = kernels.split_solve_numpy(L, D, f.perm, m, b, y)
    assert np.abs(out["two"][0] - r_ref).max() <= 1e-12 * np.abs(r_ref).max()
    assert np.abs(out["two"][1] - u_ref).max() <= 1e-12 * np.abs(u_ref).max()


def test_cholmod_factor_equals_numpy():
    """ldl.Factor's D and L_GG against ldl_numpy (dense Cholesky) in the same order."""
    module_c = ldl.load()
    if module_c is None:
        pytest.skip("CHOLMOD not available")
    import scipy.sparse as sp
    A = _spd(30, seed=7)
    S = sp.csr_matrix(A)
    perm = np.random.default_rng(1).permutation(30)
    f = ldl.Factor(module_c, S.indptr, S.indices, S.data, perm, 5, blocks=False)
    L, D = ldl.ldl_numpy(A, perm)
    assert np.abs(f.D - D).max() <= 1e-13 * np.abs(D).max()
    assert np.abs(f.L_GG - L[25:, 25:]).max() <= 1e-13


# ------------------------------------------------------------------ the build
LIBRARIES = {
    "cells": (kernels.CELL_KERNELS, ["app/kernels/perzyna.py",
                                     "app/kernels/sweeps.py",
                                     "app/kernels/cells.py", "app/kernels/contact.py",
                                     "app/model/strain.py"]),
    "dense": (dense.DENSE, ["app/solvers/dense.py"]),
    "cholmod": (ldl.CHOLMOD, ["app/solvers/ldl.py"]),
    "mumps": (mumps.MUMPS, ["app/solvers/mumps.py"]),
}


def _declared(cdef: str) -> set[str]:
    return set(re.findall(r"\b(\w+)\s*\(", cdef))


def test_read_cdef_keeps_the_prototypes_only():
    header = ("/* a comment\n   over lines */\n#ifndef X_H\n#define X_H\n"
              "// another\nint f(int a,\n      double *b);   /* f */\n#endif\n")
    assert build.read_cdef(header) == "int f(int a,\n      double *b);"


@pytest.mark.parametrize("name", LIBRARIES)
def test_header_declares_every_function_the_wrappers_call(name):
    """The cdef read from the headers parses (cffi), declares every lib.<function> of the
    wrapper modules, and every declared function is defined in the .c files (and exported by
    the library where it can be built)."""
    import cffi
    library, wrappers = LIBRARIES[name]
    cdef = library.cdef()
    cffi.FFI().cdef(cdef)
    declared = _declared(cdef)
    called = set()
    for path in wrappers:
        called |= set(re.findall(r"\blib\.(\w+)\s*\(", (ROOT / path).read_text()))
    assert called and called <= declared, called - declared
    source = "".join(p.read_text() for p in library.sources())
    for fn in declared:
        assert re.search(rf"^[\w ]+\*?{fn}\(", source, re.M), fn
    mod = library.load()
    if mod is not None:
        assert all(hasattr(mod.lib, fn) for fn in declared)


def test_every_c_file_belongs_to_a_library():
    here = build.HERE
    used = {p.name for lib, _ in LIBRARIES.values() for p in (*lib.sources(), *lib.headers())}
    assert used == {p.name for p in (*here.glob("*.c"), *here.glob("*.h"))}


def test_no_c_source_in_python_files():
    """The C lives in .c/.h files: no Python file of the application holds C source."""
    c_source = re.compile(r"#include|#define|for \(int |\brestrict\b"
                          r"|\b(?:double|int|void)\s*\*?\s*\w+\s*\([^()]*\)\s*[;{]")
    offenders = [str(p.relative_to(ROOT)) for p in (ROOT / "app").rglob("*.py")
                 if c_source.search(p.read_text())]
    assert offenders == []


def test_the_name_hashes_every_file(tmp_path, monkeypatch):
    """A change to any .c or .h (a comment too), the flags or the libraries is a new cache
    entry; the package's location is not part of it."""
    for p in build.HERE.glob("*.[ch]"):
        (tmp_path / p.name).write_text(p.read_text())
    lib = kernels.CELL_KERNELS
    name = lib.name()
    monkeypatch.setattr(build, "HERE", tmp_path)
    assert lib.name() == name                               # moved: the same entry
    names = {name}
    for part in ("contact.h", "cells.c"):
        f = tmp_path / part
        f.write_text(f.read_text() + "/* changed */\n")
        names.add(lib.name())
    monkeypatch.setattr(build, "CFLAGS", [*build.CFLAGS, "-g"])
    names.add(lib.name())
    names.add(build.Library(lib.prefix, lib.parts, lib.what).name())   # no libm
    assert len(names) == 5


def test_no_compiler_falls_back_to_numpy(tmp_path, monkeypatch, caplog):
    """Where nothing can be built (here: the compiler fails), every load returns None with
    a warning, and the numpy references serve."""
    from vpcontact.model.contact_laws import (
        ContactLaw,
        NormalCompliance,
        PiecewiseLinearFriction,
        RegularisedNorm,
    )
    from vpcontact.solvers.nodal import NodalContact

    def no_compiler(*args, **kwargs):
        raise RuntimeError("no C compiler")
    monkeypatch.setattr(build, "cache_dir", lambda: tmp_path / "kernels")
    monkeypatch.setattr(build, "_MODULES", {})
    monkeypatch.setattr(build, "_build", no_compiler)
    with caplog.at_level("WARNING", logger="vpcontact"):
        assert kernels.load() is None and dense.load() is None and ldl.load() is None
    assert caplog.text.count("unavailable (no C compiler)") == 3
    assert "using numpy" in caplog.text and "using SuperLU" in caplog.text
    law = ContactLaw(NormalCompliance(100.0), friction=PiecewiseLinearFriction(
        1.0, 60.0, 60.0, 0.01), norm=RegularisedNorm(1e-7))
    contact = NodalContact(np.ones(2), [0.0, -1.0], law, kernels.load())
    e, g, H = contact.evaluate(np.array([[0.0, -0.01], [0.02, 0.0]]))
    assert np.isfinite(e) and g.shape == (2, 2) and H.shape == (2, 2, 2)
    direction = dense.NewtonDirection(np.eye(4), 2, dense.load())
    assert np.array_equal(direction(np.zeros((2, 2, 2)), np.ones(4), np.zeros(4, bool)),
                          -np.ones(4))
