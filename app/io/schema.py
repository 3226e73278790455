"""Moved to vpcontact.case.schema; this name stays until the imports are updated."""
import sys

from vpcontact.case import schema  # moved: temporary re-export

sys.modules[__name__] = schema
