"""Reading the TOML files users give (tool tables, machines, patches) into one clear error line."""
from __future__ import annotations

import tomllib

from .errors import InputError


def read_toml(path, what: str, noun: str) -> dict:
    """The table of the TOML file at ``path``; :class:`InputError` "``path``: not ``what``" when
    it does not parse and "cannot read the ``noun``" when it cannot be read."""
    try:
        with open(path, "rb") as fh:
            return tomllib.load(fh)
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: not {what} ({exc})") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read the {noun} ({exc.strerror})") from None
