"""ASTM F3411 (Open Drone ID) broadcast Remote ID: messages, codec, capture reader."""

from registry.remoteid.codec import (
    decode,
    decode_hex,
    decode_rows,
    decode_rows_raw,
    encode,
    flatten,
    location_time,
    split_raw,
)
from registry.remoteid.errors import CaptureError, RemoteIdError
# The message classes are re-exported as the package's public surface (the codec imports the
# same list for its own use: a deliberate repeat).
from registry.remoteid.messages import (
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
# DRIP authentication lives in registry.remoteid.drip (not imported here: a check that
# meets no authentication pages does not load it).
