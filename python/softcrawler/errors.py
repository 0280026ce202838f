"""The package's exceptions."""

from __future__ import annotations

import numbers


class SoftCrawlerError(Exception):
    """Base class of the package's exceptions."""


class InvalidInput(SoftCrawlerError, ValueError):
    """An input that is not allowed. `field` names it (a scenario key such as
    ``friction.n_f``, or an argument), `value` is what was given and `allowed` what would be
    accepted: the same three the programs print (``invalid FIELD = VALUE: allowed ...``)."""

    def __init__(self, message: str, field: str, value: str, allowed: str) -> None:
        super().__init__(message)
        self.field = field
        self.value = value
        self.allowed = allowed


class RunError(SoftCrawlerError, RuntimeError):
    """A run that could not go on (a step discarded, a plant that went away, ...).
    `exit_code` is set when a co-simulated run ended otherwise than finished (the controller's
    exit code, docs of `crawler-controller run`)."""

    exit_code: int | None = None


def invalid(field: str, value: object, allowed: str) -> InvalidInput:
    """The :class:`InvalidInput` of ``field`` given ``value`` (as the programs print it)."""
    shown = repr(value)
    return InvalidInput(f"invalid {field} = {shown}: allowed {allowed}", field, shown, allowed)


#: The largest count the library takes (an unsigned 64-bit number).
MAX_COUNT = 2**64 - 1


def whole(field: str, value: object, low: int = 0, high: int = MAX_COUNT) -> int:
    """``value`` as an ``int`` in ``[low, high]`` (a Python or NumPy integer, not a bool), else
    :class:`InvalidInput` naming ``field``."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) \
            or not low <= int(value) <= high:
        allowed = f"a whole number >= {low}" if high == MAX_COUNT else \
            f"a whole number in [{low}, {high}]"
        raise invalid(field, value, allowed)
    return int(value)
