"""A law written as a user would, for --law-module in the tests, that fails on one MPI rank
only: UserPerzyna (perzyna_law.py) whose G is NaN in every cell of rank ``rank`` at the
explicit update of step ``step`` (the other ranks' cells are fine), so that the run's
failure must reach the other ranks."""
import importlib.util
from pathlib import Path

import numpy as np
from mpi4py import MPI


def _user_perzyna():
    """UserPerzyna of perzyna_law.py beside this file (a law module is not on sys.path)."""
    spec = importlib.util.spec_from_file_location(
        "failing_law_perzyna", Path(__file__).with_name("perzyna_law.py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.UserPerzyna


UserPerzyna = _user_perzyna()


class FailsOnRank(UserPerzyna):
    """UserPerzyna, NaN in G on rank ``rank`` at step ``step`` of the explicit scheme.

    The steps are counted by the calls of G over more than 8 cells (a rank's cells: at least
    16 on the tests' 4 x 4 mesh, one or two ranks; the probe before the first step takes
    m + 5 = 6 cells) at a stress it was called at before: the explicit update of step n
    evaluates G at the state of step n - 1, which the run's error estimate
    (app/post/estimators.py) evaluated first, at the end of step n - 1 (with the state
    perturbed by the propagated error too: those calls are new stresses, not counted).
    """

    name = "fails on one rank"

    def __init__(self, elasticity, lambda1, lambda2, step, rank):
        super().__init__(elasticity, lambda1, lambda2)
        self.step, self.rank, self.calls = int(step), int(rank), 0
        self.seen = set()

    def G(self, sigma, eps, kappa):
        g = super().G(sigma, eps, kappa)
        if len(sigma) > 8:
            key = np.ascontiguousarray(sigma).tobytes()
            if key in self.seen:
                self.calls += 1
                if self.calls == self.step and MPI.COMM_WORLD.rank == self.rank:
                    g[:] = np.nan
            self.seen.add(key)
        return g
