"""Compiled kernels: C files of this package, built once with cffi and cached (build.py).

The C sources and their headers live beside the Python wrappers, one pair per job:
    perzyna.c/.h      the explicit Perzyna update (3.2)-(3.3)      perzyna.py
    ldl_blocks.c/.h   the condensed solver's split solve (blocks)  sweeps.py
    contact.c/.h      the nodal contact energy (4.1)-(4.2)          contact.py
    cells.c/.h        the cell-strain operator                      cells.py
    dense.c/.h        the Gamma3 problem's Newton direction         app/solvers/dense.py
    cholmod_ldl.c/.h  CHOLMOD's L D L^T                              app/solvers/ldl.py
    mumps_schur.c/.h  MUMPS with Gamma3 Schur variables (mpirun)    app/solvers/mumps.py
Each wrapper module has the numpy reference of its kernel beside it; the tests compare them,
and the numpy (or PETSc, SuperLU) path is the fallback where no C compiler is available.
The first four are one library (``load``); dense, CHOLMOD and MUMPS link LAPACK, libcholmod
and libdmumps and are built by their modules.
"""
from __future__ import annotations

from pathlib import Path

from vpcontact.kernels.build import Library, buf, cache_dir, compiled, module_name
from vpcontact.kernels.cells import cell_load, cell_load_numpy, cell_pass, cell_pass_numpy
from vpcontact.kernels.perzyna import PerzynaKernel
from vpcontact.kernels.sweeps import GLastSolve, block_size, split_solve_numpy

__all__ = [
    "CELL_KERNELS", "GLastSolve", "Library", "PerzynaKernel", "block_size", "buf", "cache_dir",
    "cell_load", "cell_load_numpy", "cell_pass", "cell_pass_numpy", "compiled", "library_file",
    "load", "module_name", "split_solve_numpy",
]

CELL_KERNELS = Library("_vpcontact_kernels", ("perzyna", "ldl_blocks", "contact", "cells"),
                       "compiled cell kernels (using numpy)", libraries=("m",))


def load():
    """The compiled cell kernels: Perzyna update, split-solve sweeps, nodal contact energy,
    cell passes.

    Returns:
        The cffi module (``.lib``, ``.ffi``), or None (numpy is used then).
    """
    return CELL_KERNELS.load()


def library_file() -> Path:
    """The cache file of the compiled cell kernels (``load`` builds it).

    Returns:
        Its path in cache_dir().
    """
    return CELL_KERNELS.library_file()
