"""vpcontact: viscoplastic contact with normal compliance, unilateral constraint and
nonmonotone friction (Wang & Cheng 2021), on FEniCSx/dolfinx 0.5.2."""
import os as _os
import signal as _signal
import sys as _sys

# The one statement of the version: pyproject.toml reads it from here (a literal, so
# setuptools reads it without importing the package).
__version__ = "0.1.0"


def _interrupted_while_starting(signum, frame):
    """Ctrl-C or SIGTERM while `python -m app` loads its modules: one line, exit 3 (the
    CLI takes the signals over once it runs, app/cli/main.py take_signals)."""
    _os.write(2, b"vpcontact: interrupted while starting; nothing was computed\n")
    _os._exit(3)


if _sys.argv[:1] == ["-m"]:      # `python -m app` (./vpcontact) is starting: argv[0] is "-m"
    for _sig in (_signal.SIGINT, _signal.SIGTERM):
        _signal.signal(_sig, _interrupted_while_starting)

# Multithreaded OpenBLAS makes the small dense per-cell algebra 30-100x slower on these
# machines; set before numpy is imported anywhere in the application.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS"):
    _os.environ.setdefault(_var, "1")

# Open MPI (and tempfile) keep their session files under $TMPDIR: one that is not a writable
# directory makes MPI_Init print pages of mkdir errors.  It is dropped (the system's /tmp
# serves) with one warning line, by the first rank only.
_tmp = _os.environ.get("TMPDIR")
if _tmp and not (_os.path.isdir(_tmp) and _os.access(_tmp, _os.W_OK | _os.X_OK)):
    del _os.environ["TMPDIR"]
    if _os.environ.get("OMPI_COMM_WORLD_RANK", _os.environ.get("PMIX_RANK", "0")) == "0":
        from app.io.messages import warning as _warning
        _warning(f"TMPDIR={_tmp!r} is not a writable directory, ignored", rank=0)

# A run started without mpirun is an Open MPI singleton.  Its MPI_Init probes the UCX network
# layer and starts a runtime daemon: 0.29 s of a 3 s run (measured; 0.04 s with these).  One
# process communicates with nobody, so the shared-memory/self transports suffice.  Runs under
# a launcher (mpirun, srun) keep the launcher's settings; any variable already set wins.
_added = []
if not any(_v in _os.environ for _v in ("OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "PMI_RANK",
                                         "PMI_SIZE")):
    for _var, _val in (("OMPI_MCA_pml", "ob1"), ("OMPI_MCA_btl", "self"),
                       ("OMPI_MCA_osc", "^ucx"), ("OMPI_MCA_ess_singleton_isolated", "1")):
        if _var not in _os.environ:
            _os.environ[_var] = _val
            _added.append(_var)
from mpi4py import MPI as _MPI  # MPI_Init reads the settings now

for _var in _added:              # not inherited by child processes (mpirun -n 2 from here)
    del _os.environ[_var]

from app.io.cachedirs import start as _start_caches
from app.startup import install_pkg_resources_stand_in as _stand_in

# Every cache writable, or replaced by a temporary one: before dolfinx reads its JIT cache
# directory (when it is imported) and before anything is computed.
_start_caches(_MPI.COMM_WORLD.rank)

_stand_in()                      # before ufl/ffcx: see app/startup.py
