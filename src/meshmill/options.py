"""An option defined once: its name, kind, unit, default, range and help (:class:`Option`), and an
operation's options as one class (:class:`Params`, see :mod:`meshmill.params`).

Everything else is derived from these: the command line's flags and help (``step_down`` is
``--step-down``), the API's keyword arguments and their checking, a job file's checking, and the
error messages, which name the parameter (``InputError(param="step_down")``) and leave its
spelling to the caller. A value of the wrong type is refused the same way wherever it comes from:
a number given as text (``"1"``), a boolean as text (``"false"``), a table where a number is
wanted. Units: mm, degrees, mm/min.
"""
from __future__ import annotations

import dataclasses
import math
import numbers
from dataclasses import dataclass

from .errors import InputError

KINDS = ("number", "integer", "flag", "choice", "text", "numbers", "object")


class _Required:
    def __repr__(self):
        return "required"


REQUIRED = _Required()


def _is_number(v) -> bool:
    return isinstance(v, numbers.Real) and not isinstance(v, bool)


def _shown(v) -> str:
    """A value as an error message quotes it (text in quotes, so that '1' is not taken for 1)."""
    text = repr(v) if isinstance(v, str) else f"{v!r}" if not _is_number(v) else f"{v:g}"
    return text if len(text) <= 60 else text[:57] + "..."


def _looks_numeric(text: str) -> bool:
    try:
        float(text.replace(",", " ").split()[0])
        return True
    except (ValueError, IndexError):
        return False


@dataclass(frozen=True)
class Option:
    """One option. ``kind``: number, integer, flag (true/false), choice (one of ``choices``),
    text, numbers (``count`` of them: a point X,Y,Z) or object (a part, tools, a stock...: checked by the API's
    converter of that ``role``). ``default``: :data:`REQUIRED` or a value (None: off, or chosen
    by the operation, as ``help`` says). Bounds: ``low``/``high`` inclusive, ``above``/``below``
    exclusive. ``words``: values a number also accepts (``"auto"``); ``what``: what the value must be, where
    the kind does not say it well. ``cli``: False keeps
    it off the command line; ``aliases``: command-line flags that give it as ``prefix`` + their
    value (``{"--stock-allowance": "offset:"}``)."""

    kind: str
    help: str
    default: object = REQUIRED
    unit: str = ""
    low: float | None = None
    high: float | None = None
    above: float | None = None
    below: float | None = None
    choices: tuple = ()
    words: tuple = ()
    count: int = 3
    what: str = ""
    role: str = ""
    metavar: str = ""
    cli: bool = True
    positional: bool = False
    aliases: tuple = ()
    name: str = ""

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ValueError(f"option kind {self.kind!r}")

    @property
    def required(self) -> bool:
        return self.default is REQUIRED

    @property
    def flag(self) -> str:
        return "--" + self.name.replace("_", "-")

    # ------------------------------------------------------------ what it wants

    def wants(self) -> str:
        """What a value must be, as an error message says it (``a positive number of mm``)."""
        if self.what:
            return self.what
        unit = f" {self.unit}" if self.unit else ""
        of = f" of{unit}" if self.unit else ""
        if self.kind in ("number", "integer"):
            noun = "number" if self.kind == "number" else "whole number"
            if self.above == 0 and self.high is None and self.below is None and self.low is None:
                text = f"a positive {noun}{of}"
            elif self.low is not None and self.high is not None:
                text = f"a {noun}{of} from {self.low:g} to {self.high:g}"
            elif self.low is not None and self.below is not None:
                text = f"a {noun}{of} from {self.low:g} to below {self.below:g}"
            elif self.low is not None:
                text = f"a {noun}{of} >= {self.low:g}"
            elif self.above is not None:
                text = f"a {noun}{of} > {self.above:g}"
            elif self.high is not None:
                text = f"a {noun}{of} <= {self.high:g}"
            else:
                text = f"a {noun}{of}"
            return text + "".join(f" or {w!r}" for w in self.words)
        if self.kind == "flag":
            return "true or false"
        if self.kind == "choice":
            return "one of " + ", ".join(str(c) for c in self.choices)
        if self.kind == "numbers":
            what = "X,Y,Z" if self.count == 3 else f"[{', '.join('n' * self.count)}]"
            return f"{self.count} numbers {what}{f' ({self.unit})' if self.unit else ''}"
        if self.kind == "text":
            return "text" + "".join(f" or '{w}'" for w in self.words)
        return self.help

    def refuse(self, value, why: str = "") -> InputError:
        text = " (text: a number is written without quotes)" if isinstance(value, str) and self.kind in (
            "number", "integer", "numbers") and _looks_numeric(value) else \
            " (text: true and false are written without quotes)" if isinstance(value, str) and self.kind == "flag" \
            else ""
        return InputError(f"{self.name} must be {why or self.wants()}, got {_shown(value)}{text}", self.name)

    # ------------------------------------------------------------ checking

    def check(self, value):
        """``value`` as the operation takes it (an integer as int, a number as float), or
        :class:`InputError` naming the parameter. Objects are left to their converter."""
        if value is None and (self.default is None or self.kind == "object"):
            return None
        if self.kind == "object":
            return value
        if any(value is w or type(value) is type(w) and value == w for w in self.words):
            return value
        if self.kind in ("number", "integer"):
            if not _is_number(value):
                raise self.refuse(value)
            v = float(value)
            if not math.isfinite(v):
                raise self.refuse(value)
            if self.kind == "integer":
                if not v.is_integer():
                    raise self.refuse(value)
                v = int(v)
            if (self.low is not None and v < self.low or self.high is not None and v > self.high
                    or self.above is not None and v <= self.above or self.below is not None and v >= self.below):
                raise self.refuse(value)
            return v
        if self.kind == "flag":
            if not isinstance(value, bool):
                raise self.refuse(value)
            return value
        if self.kind == "choice":
            for c in self.choices:
                if value == c and type(value) is type(c) or isinstance(c, str) and isinstance(value, int) \
                        and not isinstance(value, bool) and str(value) == c:
                    return c
            raise self.refuse(value)
        if self.kind == "text":
            if not isinstance(value, str) or not value.strip():
                raise self.refuse(value)
            return value
        if self.kind == "numbers":
            if isinstance(value, str) or not hasattr(value, "__len__") or len(value) != self.count or \
                    not all(_is_number(x) and math.isfinite(float(x)) for x in value):
                raise self.refuse(value)
            return tuple(float(x) for x in value)
        raise AssertionError(self.kind)

    def from_text(self, text: str):
        """A command-line value: ``text`` turned into the kind (objects stay text)."""
        if self.kind == "object" or text in (str(w) for w in self.words):
            return text
        if self.kind in ("number", "integer"):
            try:
                v = float(text)
            except ValueError:
                raise self.refuse(text) from None
            return int(v) if self.kind == "integer" and v.is_integer() else v
        if self.kind == "choice":
            for c in self.choices:
                if str(c) == text:
                    return c
            raise self.refuse(text)
        if self.kind == "numbers":
            try:
                return tuple(float(x) for x in text.replace(" ", "").split(","))
            except ValueError:
                raise self.refuse(text) from None
        return text

    def help_text(self) -> str:
        """The command line's help: what it is, its unit and its default (where the help does not
        say it already)."""
        text = f"{self.help}, {self.unit}" if self.unit else self.help
        if self.required or self.kind == "flag" or "default" in self.help:
            return text
        d = self.default
        if d is None:
            shown = "off"
        elif isinstance(d, tuple):
            shown = ",".join(f"{x:g}" if _is_number(x) else str(x) for x in d)
        else:
            shown = f"{d:g}" if _is_number(d) else str(d)
        return f"{text} ({shown})"


def option(kind: str, help: str, default=REQUIRED, **kw) -> dataclasses.Field:
    """A field of a :class:`Params` class that is an :class:`Option`."""
    opt = Option(kind, help, default, **kw)
    return dataclasses.field(default=None if default is REQUIRED else default, metadata={"option": opt})


class Params:
    """An operation's options as a frozen dataclass whose fields are :func:`option` fields (in
    the order the API's signature lists them); :meth:`check` adds the checks between options."""

    @classmethod
    def options(cls) -> dict[str, Option]:
        """The options by name, in order."""
        found = cls.__dict__.get("_options")
        if found is None:
            found = {f.name: dataclasses.replace(f.metadata["option"], name=f.name)
                     for f in dataclasses.fields(cls) if "option" in f.metadata}
            cls._options = found
        return found

    @classmethod
    def checked(cls, values: dict, what: str = "") -> "Params":
        """The params of ``values`` (name -> value): unknown names, missing required ones and values
        of the wrong kind or out of range are refused (:class:`InputError` naming them); then
        :meth:`check`."""
        opts = cls.options()
        unknown = sorted(set(values) - set(opts))
        if unknown:
            known = ", ".join(n for n in opts)
            raise InputError(f"unknown parameter{'s' * (len(unknown) > 1)} {', '.join(map(str, unknown))}"
                             f"{f' for {what}' if what else ''} (it takes {known})", tuple(map(str, unknown)))
        out = {}
        for name, opt in opts.items():
            if name in values:
                out[name] = opt.check(values[name])
            elif opt.required:
                raise InputError(f"{name} is required ({opt.help}{f', {opt.unit}' if opt.unit else ''})", name)
        params = cls(**out)
        params.check()
        return params

    def check(self) -> None:
        """Checks between options (one of two given, one below another); raises :class:`InputError`."""

    def replace(self, **changes) -> "Params":
        return dataclasses.replace(self, **changes)
