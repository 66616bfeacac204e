"""Errors of the radar layer that are the caller's fault (exit code 2)."""

from core.errors import BadInput

__all__ = ["SignaturesError", "RecordingError"]


class SignaturesError(BadInput):
    """Bad radar input (file, configuration, profile): a one-line message."""


class RecordingError(SignaturesError):
    """A recorded-return file that does not meet the format (docs/format.md)."""
