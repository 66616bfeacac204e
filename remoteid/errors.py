"""Errors of the Remote ID codec and capture reader (all bad input, exit code 2)."""

from core.errors import BadInput


class RemoteIdError(BadInput):
    """A Remote ID message that cannot be decoded or encoded (one-line reason)."""


class CaptureError(RemoteIdError):
    """A pcap/pcapng file that cannot be read."""
