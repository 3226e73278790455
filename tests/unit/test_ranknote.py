"""The run log's note on a small case under mpirun (app/cli/ranknote.py): only for several
ranks with fewer than SMALL_DOFS_PER_RANK dofs each, with the split it is given."""
from vpcontact.cli.ranknote import SMALL_DOFS_PER_RANK, small_case_note


def test_small_case_note():
    assert small_case_note(1, 100, 1.0, 1.0, 1.0) is None
    assert small_case_note(2, 2 * SMALL_DOFS_PER_RANK, 1.0, 1.0, 1.0) is None
    note = small_case_note(2, 3356, 1.234, 0.5, 0.75)
    assert note.startswith("mpirun -n 2 on 1,678 dofs per rank: start-up 1.23 s")
    assert "set-up 0.50 s, steps 0.75 s" in note and "\n" not in note
