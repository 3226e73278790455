"""The command line's process: the environment set up before anything heavy is imported.

Importing the package ``vpcontact`` changes nothing in the process; the command line (``python
-m vpcontact``, ``./vpcontact``, the ``vpcontact`` console script) calls ``console``, which
first prepares the process (``prepare_process``) and then runs ``main``.
"""
import os
import signal
import sys


def _interrupted_while_starting(signum, frame):
    """Ctrl-C or SIGTERM while the modules load: one line, exit 3 (``main`` takes the
    signals over once it runs, app/cli/main.py take_signals)."""
    os.write(2, b"vpcontact: interrupted while starting; nothing was computed\n")
    os._exit(3)


def _usable_tmpdir() -> None:
    """Open MPI (and tempfile) keep their session files under $TMPDIR: one that is not a
    writable directory makes MPI_Init print pages of mkdir errors.  It is dropped (the
    system's /tmp serves) with one warning line, by the first rank only."""
    tmp = os.environ.get("TMPDIR")
    if tmp and not (os.path.isdir(tmp) and os.access(tmp, os.W_OK | os.X_OK)):
        del os.environ["TMPDIR"]
        if os.environ.get("OMPI_COMM_WORLD_RANK", os.environ.get("PMIX_RANK", "0")) == "0":
            from vpcontact.io.messages import warning
            warning(f"TMPDIR={tmp!r} is not a writable directory, ignored", rank=0)


def mpi_settings(env) -> tuple:
    """The Open MPI settings of a process: a light singleton without a launcher; under
    Open MPI's mpirun with every rank on this node (``OMPI_COMM_WORLD_LOCAL_SIZE`` =
    ``OMPI_COMM_WORLD_SIZE``) the ob1 messaging layer (shared memory) named, so that
    MPI_Init does not open the others first (cm loads and probes the psm/psm2 network
    libraries, then ob1 is selected all the same); none under other launchers (srun,
    MPICH: PMI_*) or across nodes, which keep theirs.

    Args:
        env: the process's environment (a mapping).

    Returns:
        (variable, value) pairs; ``_init_mpi`` sets those not already set.
    """
    if not any(v in env for v in ("OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "PMI_RANK", "PMI_SIZE")):
        return (("OMPI_MCA_pml", "ob1"), ("OMPI_MCA_btl", "self"), ("OMPI_MCA_osc", "^ucx"),
                ("OMPI_MCA_ess_singleton_isolated", "1"))
    if env.get("OMPI_COMM_WORLD_SIZE") and \
            env.get("OMPI_COMM_WORLD_LOCAL_SIZE") == env["OMPI_COMM_WORLD_SIZE"]:
        return (("OMPI_MCA_pml", "ob1"),)
    return ()


def _init_mpi():
    """Initialise MPI; a run without a launcher as a light Open MPI singleton, a run under
    mpirun on one node with the ob1 layer named (``mpi_settings``).

    A singleton's MPI_Init probes the UCX network layer and starts a runtime daemon, a
    noticeable part of a short run.  One process communicates with nobody, so the
    shared-memory/self transports suffice.  Under mpirun, opening the other messaging layers
    costs every rank part of its start-up for the same choice (both: docs/performance.md,
    section 5; Debian's openmpi-mca-params.conf excludes UCX; ob1 is selected either
    way, so results do not change).  Runs across nodes or under other launchers keep the
    launcher's settings; any variable already set (``mpirun --mca``) wins.
    """
    added = []
    for var, val in mpi_settings(os.environ):
        if var not in os.environ:
            os.environ[var] = val
            added.append(var)
    from mpi4py import MPI  # MPI_Init reads the settings now
    for var in added:                 # not inherited by child processes (mpirun -n 2 from here)
        del os.environ[var]
    return MPI


def prepare_process() -> None:
    """Set up the command line's process, before numpy, MPI, ufl or dolfinx are imported.

    One BLAS thread (multithreaded OpenBLAS makes the small dense per-cell algebra much slower:
    docs/performance.md, section 5; the large operations widen it, app/threads.py), OpenBLAS's
    idle threads asleep after 2^20 cycles instead of 2^28 (OPENBLAS_THREAD_TIMEOUT), one OpenMP
    thread (OMP_THREAD_LIMIT: CHOLMOD's loops ask for 4), a usable TMPDIR, MPI initialised (a
    light singleton without a launcher), every cache writable or replaced (before dolfinx reads
    its JIT cache directory), the stand-in for ``pkg_resources``
    (app/startup.py) and usable standard streams.
    """
    for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS"):
        os.environ.setdefault(var, "1")
    # a thread of the Gamma3 work's BLAS spinning on after it took a core from the
    # two-thread sweeps; 20 leaves the dense work as fast (docs/performance.md, section 7)
    os.environ.setdefault("OPENBLAS_THREAD_TIMEOUT", "20")
    # CHOLMOD's supernodal factorisation runs its scatter loops on 4 OpenMP threads (a
    # constant compiled into libcholmod, whatever OMP_NUM_THREADS says); on 2 cores their
    # spinning slows the set-up and gains nothing (docs/performance.md, section 5): one
    # thread (read by libgomp when it loads, with libcholmod, after this)
    os.environ.setdefault("OMP_THREAD_LIMIT", "1")
    _usable_tmpdir()
    MPI = _init_mpi()
    from vpcontact.io.cachedirs import start
    from vpcontact.startup import install_pkg_resources_stand_in
    start(MPI.COMM_WORLD.rank)
    install_pkg_resources_stand_in()     # before ufl/ffcx: see app/startup.py
    from vpcontact.cli.streams import repair_std_streams
    repair_std_streams()                 # before ufl keeps a reference to sys.stdout


def console() -> None:
    """The command line: ``python -m vpcontact``, ``./vpcontact`` and the console script."""
    from vpcontact.startup import pause_collector
    pause_collector()                    # until the run is set up (app/startup.py)
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, _interrupted_while_starting)
    prepare_process()
    from vpcontact.cli.ending import hold_signals, signal_at_exit
    from vpcontact.cli.main import main
    from vpcontact.startup import quick_exit
    quick_exit(main(sys.argv[1:], process=True), last=signal_at_exit, after_petsc=hold_signals)
