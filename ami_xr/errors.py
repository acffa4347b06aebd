"""Exception and warning types of ami_xr.

Every error a user can cause by bad input is a :class:`ValueError` subclass whose message names the
variable, file or argument and says what was expected.
"""

from __future__ import annotations


class AmiXrError(Exception):
    """Base class of every ami_xr exception."""


class AmiXrValueError(AmiXrError, ValueError):
    """A bad argument value: the message names the argument and what was expected."""


class SchemaError(AmiXrValueError):
    """A Dataset does not follow the ami_xr data model.

    ``problems`` lists every problem found, each naming the variable and what was expected.
    """

    def __init__(self, problems: list[str], what: str = "Dataset"):
        self.problems = list(problems)
        lines = "\n".join(f"  - {p}" for p in self.problems)
        super().__init__(
            f"{what} does not follow the ami_xr data model "
            f"({len(self.problems)} problem(s)):\n{lines}"
        )


class DataFileError(AmiXrValueError):
    """A file could not be read or written: missing, truncated, or not the expected format."""


class IdentificationError(AmiXrValueError):
    """Identification cannot run on the given data or parameters."""


class AmiXrWarning(UserWarning):
    """Base class of ami_xr warnings."""


class ConvergenceWarning(AmiXrWarning):
    """An iteration stopped at its cap before meeting its tolerance."""


class CapWarning(ConvergenceWarning):
    """A phase stopped at a cap. ``status`` holds the cap's bits (an int of
    :class:`ami_xr.core.flags.RunStatus`), so that a caller tells the caps apart by value, never
    by the text of the message."""

    def __init__(self, message: str, status: int = 0) -> None:
        super().__init__(message)
        self.status = int(status)


class NoModesWarning(AmiXrWarning):
    """No mode could be identified (for example an FRF that is pure noise)."""


class AssumptionWarning(AmiXrWarning):
    """A reader or estimator assumed something the user did not give (drive point, excitation);
    the message says what and how to set it."""
