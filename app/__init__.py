"""vpcontact: viscoplastic contact with normal compliance, unilateral constraint and
nonmonotone friction (Wang & Cheng 2021), on FEniCSx/dolfinx 0.5.2."""
import os as _os

# Multithreaded OpenBLAS makes the small dense per-cell algebra 30-100x slower on these
# machines; set before numpy is imported anywhere in the application.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS"):
    _os.environ.setdefault(_var, "1")

__version__ = "0.1.0"
