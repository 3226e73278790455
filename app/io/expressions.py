"""Moved to vpcontact.case.expressions; this name stays until the imports are updated."""
import sys

from vpcontact.case import expressions  # moved: temporary re-export

sys.modules[__name__] = expressions
