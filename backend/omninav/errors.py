"""One exception type for everything a user can get wrong; the CLI prints its message, no traceback."""


class OmninavError(Exception):
    """Bad input or state that the user can fix: the message says what was wrong."""
