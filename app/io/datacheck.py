"""Moved to vpcontact.case.datacheck; this name stays until the imports are updated."""
import sys

from vpcontact.case import datacheck  # moved: temporary re-export

sys.modules[__name__] = datacheck
