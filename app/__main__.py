"""``python -m vpcontact``: the command line (app/cli/entry.py)."""
from vpcontact.cli.entry import console

console()      # an exception propagates as usual (traceback, exit status 1)
