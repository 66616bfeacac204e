"""ASTM F3411 (Open Drone ID) broadcast Remote ID: messages, codec, capture reader."""

from typing import Any

from remoteid.codec import (
    decode,
    decode_hex,
    decode_rows,
    decode_rows_raw,
    encode,
    flatten,
    location_time,
    split_raw,
)
from remoteid.errors import CaptureError, RemoteIdError
# The message classes are re-exported as the package's public surface (the codec imports the
# same list for its own use: a deliberate repeat).
from remoteid.messages import (
    AuthPage,
    AuthPage0,
    BasicId,
    Location,
    MessagePack,
    OperatorId,
    SelfId,
    System,
)

__all__ = [
    "AuthPage", "AuthPage0", "BasicId", "CaptureError", "Location", "MessagePack",
    "OperatorId", "RemoteIdError", "SelfId", "System", "decode", "decode_hex",
    "decode_rows", "decode_rows_raw", "encode", "flatten", "location_time", "split_raw",
]

# DRIP authentication (remoteid.drip) is loaded on first use of one of its names.
_DRIP = ("AuthResult", "DripError", "det_from_public_key", "det_to_text", "encode_frame",
         "encode_link", "encode_manifest", "encode_wrapper", "paginate", "parse_det", "verify")


def __getattr__(name: str) -> Any:
    if name in _DRIP:
        from remoteid import drip

        return getattr(drip, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
