"""The exception of invalid input, shared by the case reader and the option checks."""


class CaseError(ValueError):
    """An invalid case: the message names the file, the key path and what is allowed."""
