"""Moved to vpcontact.solvers.optioncheck; this name stays until the imports are updated."""
import sys

from vpcontact.solvers import optioncheck  # moved: temporary re-export

sys.modules[__name__] = optioncheck
