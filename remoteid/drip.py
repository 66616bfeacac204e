"""DRIP authentication of broadcast Remote ID (IETF DRIP: RFC 9374 DETs, RFC 9575 SAM types).

One import point; the formats are in `drip_formats`, the verification in `drip_verify`.
"""

# The public surface, re-exported (tests import the same names: a deliberate repeat).
from remoteid.drip_formats import (
    AUTH_TYPE_SAM,
    FRAME_F3411_MESSAGES,
    SAM_FRAME,
    SAM_LINK,
    SAM_MANIFEST,
    SAM_NAMES,
    SAM_WRAPPER,
    DetFields,
    DripError,
    Link,
    Signed,
    cshake128,
    det_fields,
    det_from_public_key,
    det_matches_key,
    det_to_text,
    encode_frame,
    encode_link,
    encode_manifest,
    encode_wrapper,
    from_drip_time,
    from_valid_time,
    has_fec_page,
    message_hash,
    paginate,
    parse_det,
    parse_sam,
    to_drip_time,
    to_valid_time,
    valid_time_text,
    xor_pages,
)
from remoteid.drip_verify import STATUSES, AuthMessage, AuthResult, reassemble, verify

__all__ = [
    "AUTH_TYPE_SAM", "FRAME_F3411_MESSAGES", "AuthMessage", "AuthResult", "DetFields", "DripError", "Link", "SAM_FRAME",
    "SAM_LINK", "SAM_MANIFEST", "SAM_NAMES", "SAM_WRAPPER", "STATUSES", "Signed", "cshake128",
    "det_fields", "det_from_public_key", "det_matches_key", "det_to_text", "encode_frame",
    "encode_link", "encode_manifest", "encode_wrapper", "from_drip_time", "from_valid_time", "has_fec_page",
    "message_hash", "paginate", "parse_det", "parse_sam", "reassemble", "to_drip_time", "to_valid_time",
    "valid_time_text", "verify", "xor_pages",
]
