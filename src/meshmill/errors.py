"""Errors that the command line turns into one clear line and exit code 2."""


class InputError(Exception):
    """Bad input from the user: a file, a value or a combination we cannot work with."""
