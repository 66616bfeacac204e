"""Errors of the radar layer that are the caller's fault (exit code 2)."""


class SignaturesError(ValueError):
    """Bad radar input (file, configuration, profile): a one-line message."""


class RecordingError(SignaturesError):
    """A recorded-return file that does not meet SPEC section 3."""
