"""Errors a user can cause.

Every problem that comes from the user's input (a file, a field, an argument)
raises :class:`InputError` with a message naming the file, the field and what
was expected. The command line prints it in one line and exits with status 2.
"""


class InputError(ValueError):
    """Unusable input: the message names the file (or argument), the field and what is expected."""
