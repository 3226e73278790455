"""What the code of a user (a ``--law-module``, a law object) may raise, and how a message
names it.

A user's module or law method may end with any exception and also with ``SystemExit``
(``sys.exit`` in a law): both are the user's failure, reported in one line (a refusal
before the run, a failed step during it), never a silent exit or a traceback.
``KeyboardInterrupt`` (a signal: SIGINT/SIGTERM at start-up or in a study) is not the
user's code and goes on to the command line's handler.
"""
from __future__ import annotations

USER_ERRORS = (Exception, SystemExit)


def raised(exc: BaseException) -> str:
    """The words that name what the user's code raised.

    Args:
        exc: the exception (or SystemExit).

    Returns:
        ``"raised KeyError: 'x'"``; ``"raised SystemExit"`` for ``sys.exit()`` or
        ``sys.exit(0)``, ``"raised SystemExit: 3"`` for ``sys.exit(3)``.
    """
    text = str(exc)
    if isinstance(exc, SystemExit) and exc.code in (None, 0):
        text = ""
    return f"raised {type(exc).__name__}" + (f": {text}" if text else "")
