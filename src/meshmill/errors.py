"""Errors that the command line turns into one clear line and exit code 2."""
from __future__ import annotations

import re


class InputError(Exception):
    """Bad input from the user: a file, a value or a combination we cannot work with.

    ``param``: the names of the parameters it is about (the API's keyword names, ``step_down``),
    as written in the message; :meth:`text` spells them another way (the command line's
    ``--step-down``) and :meth:`within` says where they were given (``operation 2 (rough):``)."""

    def __init__(self, message: str, param: str | tuple | list = (), where: str = ""):
        super().__init__(message)
        self.message = str(message)
        self.params = (param,) if isinstance(param, str) else tuple(param)
        self.where = where  # set by within(): the names are a file's keys, not to be spelled otherwise

    def text(self, spell=None) -> str:
        """The message with each parameter it names spelled by ``spell(name)`` (default: as is)."""
        if spell is None or not self.params or self.where:
            return self.message
        names = "|".join(re.escape(p) for p in sorted(self.params, key=len, reverse=True))
        return re.sub(rf"(?<![\w\-\[/])({names})(?![\w\-\]/])", lambda m: spell(m.group(1)), self.message)

    def within(self, where: str) -> "InputError":
        """The same error said of ``where`` (``operation 2 (rough)``, ``[stock]``)."""
        return InputError(f"{where}: {self.message}", self.params, where)

    def __str__(self) -> str:
        return self.message


class NothingToCut(InputError):
    """An operation finds nothing to cut: no contour, no level, no pass through the stock. A job
    skips the operation or refuses, as its ``nothing_to_cut`` says."""
