"""A fixed approach direction for two bodies (contact.direction with contact.pairs): every
surface node is coupled to the target's point on the line through it along the direction
(a ray cast, app/model/pairgeometry.py ``cast_points``) and the gap is measured along it,
as linear (Hertz) theory does (Johnson, Contact Mechanics, ch. 4).

On the shipped Hertz case of two cylinders (cases/two_cylinders.yaml: R1 = 1, E1 = 1000 on
R2 = 2, E2 = 2000, nu = 0.3, plane strain, frictionless, mortar rule):

- the swapped pair (the lower arc as the surface, direction +y, on a copy of the .geo with
  the lower contact arc shortened to 10 degrees) gives the same load P within 5e-4
  (measured 1.0e-4 at mesh.size = 2, 5e-6 at 1), where the pairs' own normals (the target's
  at the closest point, tests/system/test_pairs_hertz.py) differ by 0.5 % at every mesh;
- the half-width a and the peak pressure p0 of the fitted Hertz ellipse against the closed
  form hertz_cylinders(P) at two meshes, the error falling with h (measured: a -0.83 %,
  p0 +0.92 % at mesh.size = 2; -0.43 %, +0.34 % at mesh.size = 1).
"""
import pytest
from test_pairs_hertz import Run, _hertz, _raw

DOWN, UP = [0.0, -1.0], [0.0, 1.0]


def _run(size: float, swap: bool, tmp_path) -> Run:
    raw = _raw("mortar", swap, tmp_path)
    raw["mesh"]["size"] = size
    raw["contact"]["direction"] = UP if swap else DOWN
    return Run(raw, upper_is_surface=not swap)


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("direction")
    return {(size, swap): _run(size, swap, tmp) for size in (2.0, 1.0)
            for swap in (False, True) if size == 2.0 or not swap}


def test_swapped_pair_gives_the_same_load(runs):
    assert runs[(2.0, True)].P == pytest.approx(runs[(2.0, False)].P, rel=5e-4)


def test_hertz_error_falls_with_h(runs):
    errors = []
    for size in (2.0, 1.0):
        run = runs[(size, False)]
        a_ref, p0_ref = _hertz(run.P)
        a, p0 = run.fit()
        errors.append((abs(a / a_ref - 1), abs(p0 / p0_ref - 1)))
    (a2, p2), (a1, p1) = errors
    assert a2 <= 0.012 and p2 <= 0.012
    assert a1 <= 0.7 * a2 and p1 <= 0.7 * p2
