"""The package's exceptions."""

from __future__ import annotations


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
