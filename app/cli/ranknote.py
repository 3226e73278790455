"""The run log's note on a small case under mpirun: where its time went and why one rank is
usually as fast at that size (``small_case_note``)."""
from __future__ import annotations

# Below this many dofs per rank `mpirun -n 2` was never faster than one rank on the 2-core
# machines; box3d n = 32, about 54,000 per rank, is about even (whole process, interleaved
# runs: docs/performance.md, section 5).
SMALL_DOFS_PER_RANK = 50_000


def small_case_note(ranks: int, dofs: int, startup_s: float, setup_s: float,
                    loop_s: float) -> str | None:
    """One line for the run log of a run on few dofs per rank, else None.

    Args:
        ranks: the MPI ranks.
        dofs: the global dofs of u.
        startup_s: the command's start-up on rank 0 (MPI, imports, the case), seconds.
        setup_s: the run's set-up (summary.json ``setup_s``).
        loop_s: the time loop (summary.json ``loop_s``).

    Returns:
        The note, or None for one rank or at least SMALL_DOFS_PER_RANK dofs per rank.
    """
    if ranks < 2 or dofs >= SMALL_DOFS_PER_RANK * ranks:
        return None
    return (f"mpirun -n {ranks} on {dofs // ranks:,} dofs per rank: start-up {startup_s:.2f} s "
            f"(MPI, imports, the case), set-up {setup_s:.2f} s, steps {loop_s:.2f} s; below "
            f"{SMALL_DOFS_PER_RANK:,} dofs per rank one rank is usually as fast: every rank "
            "pays the whole start-up, and each step waits for the other ranks at some 15 "
            "exchanges (the Gamma3 problem on rank 0, norms, the contact table), slow on a "
            "busy machine (docs/performance.md, section 5)")
