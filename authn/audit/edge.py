"""The right edge a periodic head keeps (`audit_tree_heads.frontier`), signed by the log key.

The writer starts its extension proof from the newest periodic head's edge (authn.audit.writer).
The column is in the database, so it is never trusted as stored: the edge carries an Ed25519
signature over (origin, tree size, root, the edge's hashes), which binds it to the one head
it was made with. A database writer can then neither move the anchor to another head (a
newer one widens the part the next append does not re-hash) nor swap in another form of
edge; an edge that does not check is ignored and the writer recomputes the edge from the
stored leaf hashes instead, folding them to the signed root (slower, equally sound).
"""

from __future__ import annotations

import base64
import binascii
import hashlib
import json
from typing import TYPE_CHECKING

from authn.audit.logkey import LogKey
from authn.audit.tree_head import SignedTreeHead
from core.parsing import loads_json

if TYPE_CHECKING:
    from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PublicKey

EDGE_CONTEXT = b"authn-edge/1\n"


def _statement(sth: SignedTreeHead, before_last: list[bytes]) -> bytes:
    digest = hashlib.sha256(b"".join(before_last)).hexdigest()
    return EDGE_CONTEXT + f"{sth.origin}\n{sth.tree_size}\n{sth.root_hash}\n{digest}\n".encode()


def edge_json(key: LogKey, sth: SignedTreeHead, before_last: list[bytes]) -> str:
    """The column value of a periodic head: the edge before its last entry, signed with it."""
    sig = base64.b64encode(key.sign(_statement(sth, before_last))).decode()
    return json.dumps({"before_last": [h.hex() for h in before_last], "signature": sig})


def signed_edge(text: object, sth: SignedTreeHead, public_key: Ed25519PublicKey) -> list[bytes] | None:
    """The edge stored with `sth`, when its signature by `public_key` binds it to that head;
    None for anything else (unsigned, an old list form, altered, another head's, malformed)."""
    from cryptography.exceptions import InvalidSignature

    if not isinstance(text, (str, bytes)):
        return None
    try:
        doc = loads_json(text)
        hashes = [bytes.fromhex(h) for h in doc["before_last"]]
        sig = base64.b64decode(doc["signature"], validate=True)
        if any(len(h) != 32 for h in hashes) or len(hashes) != bin(max(sth.tree_size - 1, 0)).count("1"):
            return None
        public_key.verify(sig, _statement(sth, hashes))
    except (ValueError, TypeError, KeyError, AttributeError, binascii.Error, InvalidSignature):
        return None
    return hashes
