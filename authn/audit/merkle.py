"""RFC 9162 (Certificate Transparency v2) Merkle tree hashing and proofs, from the RFC's text.

Why our own: the algorithms are short, the RFC states them exactly, and the audit log
needs them over leaves it streams from a database (no library does that for us). Only
SHA-256 is used; nothing here signs. Section references are to RFC 9162:

- 2.1.1 MTH: leaf = SHA-256(0x00 || d), node = SHA-256(0x01 || left || right), the split
  point k is the largest power of two smaller than n; MTH({}) = SHA-256("").
- 2.1.3 inclusion proofs (audit paths): generation 2.1.3.1, verification 2.1.3.2.
- 2.1.4 consistency proofs: generation 2.1.4.1, verification 2.1.4.2.

Proof generation is written as the list of subtree *ranges* whose hashes the proof
holds; `subtree_hash` (from a list) or `RangeCollector` (one streaming pass over leaf
hashes, for verify of a million entries) turns ranges into hashes.
"""

from __future__ import annotations

import hashlib
from collections.abc import Iterable, Sequence

EMPTY_ROOT = hashlib.sha256(b"").digest()
Range = tuple[int, int]  # [start, end) in leaf indices


def leaf_hash(data: bytes) -> bytes:
    """SHA-256(0x00 || leaf bytes)."""
    return hashlib.sha256(b"\x00" + data).digest()


def node_hash(left: bytes, right: bytes) -> bytes:
    """SHA-256(0x01 || left || right)."""
    return hashlib.sha256(b"\x01" + left + right).digest()


def _split(n: int) -> int:
    """Largest power of two strictly smaller than n (n >= 2)."""
    return 1 << ((n - 1).bit_length() - 1)


# --- tree heads --------------------------------------------------------------------------

class Frontier:
    """The right edge of a growing tree: the roots of its perfect subtrees, largest first.

    Appending a leaf costs one hash plus amortised one merge; the root of the current tree
    is the right-to-left fold of the stack (this equals MTH: the RFC's recursion peels the
    largest power of two off the left, which is exactly the binary decomposition of n).
    Persisting `hashes` (at most 64 of them) lets the next checkpoint continue from here.
    """

    def __init__(self, size: int = 0, hashes: Sequence[bytes] = ()) -> None:
        if len(hashes) != bin(size).count("1"):
            raise ValueError(f"a frontier of size {size} has {bin(size).count('1')} hashes, got {len(hashes)}")
        self.size = size
        self._sizes = [1 << b for b in range(size.bit_length() - 1, -1, -1) if size >> b & 1]
        self._hashes = list(hashes)

    @property
    def hashes(self) -> list[bytes]:
        return list(self._hashes)

    def push(self, leaf: bytes) -> None:
        """Append one leaf *hash*."""
        sizes, hashes = self._sizes, self._hashes
        sizes.append(1)
        hashes.append(leaf)
        while len(sizes) > 1 and sizes[-1] == sizes[-2]:
            right = hashes.pop()
            sizes.pop()
            hashes[-1] = node_hash(hashes[-1], right)
            sizes[-1] *= 2
        self.size += 1

    def root(self) -> bytes:
        if not self._hashes:
            return EMPTY_ROOT
        acc = self._hashes[-1]
        for h in reversed(self._hashes[:-1]):
            acc = node_hash(h, acc)
        return acc


def root_hash(leaves: Iterable[bytes]) -> bytes:
    """MTH over leaf hashes."""
    f = Frontier()
    for h in leaves:
        f.push(h)
    return f.root()


def subtree_hash(leaves: Sequence[bytes], start: int, end: int) -> bytes:
    """MTH(D[start:end]) over a list of leaf hashes."""
    return root_hash(leaves[start:end])


# --- proof shapes (which subtrees a proof holds) -----------------------------------------

def inclusion_ranges(index: int, size: int) -> list[Range]:
    """PATH(m, D[n]) of 2.1.3.1 as ranges, leaf-side first."""
    if not 0 <= index < size:
        raise ValueError(f"leaf index {index} is not in a tree of size {size}")
    out: list[Range] = []
    lo, hi, m = 0, size, index
    while hi - lo > 1:
        k = _split(hi - lo)
        if m < k:
            out.append((lo + k, hi))
            hi = lo + k
        else:
            out.append((lo, lo + k))
            lo, m = lo + k, m - k
    return out[::-1]


def consistency_ranges(old: int, new: int) -> list[Range]:
    """PROOF(m, D[n]) = SUBPROOF(m, D[n], true) of 2.1.4.1 as ranges, innermost first."""
    if not 0 <= old <= new:
        raise ValueError(f"no consistency proof from size {old} to size {new}")
    if old == 0 or old == new:
        return []
    out: list[Range] = []
    lo, hi, m, whole = 0, new, old, True
    while m != hi - lo:
        k = _split(hi - lo)
        if m <= k:
            out.append((lo + k, hi))
            hi = lo + k
        else:
            out.append((lo, lo + k))
            lo, m, whole = lo + k, m - k, False
    if not whole:
        out.append((lo, hi))
    return out[::-1]


def inclusion_proof(leaves: Sequence[bytes], index: int, size: int | None = None) -> list[bytes]:
    n = len(leaves) if size is None else size
    return [subtree_hash(leaves, a, b) for a, b in inclusion_ranges(index, n)]


def consistency_proof(leaves: Sequence[bytes], old: int, new: int | None = None) -> list[bytes]:
    n = len(leaves) if new is None else new
    return [subtree_hash(leaves, a, b) for a, b in consistency_ranges(old, n)]


class RangeCollector:
    """Hashes of chosen subtree ranges (and roots at chosen sizes) in one pass over leaf hashes.

    Every range a proof can ask for is either a perfect, aligned subtree, created by a
    merge on the frontier stack at the moment its last leaf arrives, or a right-edge
    subtree [a, n) ending at the final size, which is a suffix of the stack at size n.
    """

    def __init__(self, ranges: Iterable[Range] = (), root_sizes: Iterable[int] = ()) -> None:
        self.wanted = set(ranges)
        self.root_sizes = set(root_sizes)
        self.hashes: dict[Range, bytes] = {}
        self.roots: dict[int, bytes] = {}
        self.size = 0
        self._stack: list[list] = []  # [start, size, hash]
        self._ends = {b for _, b in self.wanted} | self.root_sizes

    def push(self, leaf: bytes) -> None:
        stack, i = self._stack, self.size
        stack.append([i, 1, leaf])
        if (i, i + 1) in self.wanted:
            self.hashes[(i, i + 1)] = leaf
        while len(stack) > 1 and stack[-1][1] == stack[-2][1]:
            _, s, right = stack.pop()
            top = stack[-1]
            top[1] = s * 2
            top[2] = node_hash(top[2], right)
            r = (top[0], top[0] + top[1])
            if r in self.wanted:
                self.hashes[r] = top[2]
        self.size = i + 1
        if self.size in self._ends:
            self._at_end_of(self.size)

    def _at_end_of(self, end: int) -> None:
        acc: bytes | None = None
        for start, _, h in reversed(self._stack):
            acc = h if acc is None else node_hash(h, acc)
            if (start, end) in self.wanted and (start, end) not in self.hashes:
                self.hashes[(start, end)] = acc
        if end in self.root_sizes:
            self.roots[end] = acc if acc is not None else EMPTY_ROOT

    def root(self) -> bytes:
        acc: bytes | None = None
        for _, _, h in reversed(self._stack):
            acc = h if acc is None else node_hash(h, acc)
        return EMPTY_ROOT if acc is None else acc

    def frontier(self) -> Frontier:
        return Frontier(self.size, [h for _, _, h in self._stack])


# --- verification ------------------------------------------------------------------------

def _sides(fn: int, sn: int, path: Sequence[bytes]) -> list[tuple[bytes, bool]] | None:
    """RFC 9162's walk up a proof from node `fn` of last node `sn` (2.1.3.2 and 2.1.4.2 share it):
    each node of `path` with whether it joins on the left; None when the path does not end
    exactly at the root (too long, or too short)."""
    sides = []
    for c in path:
        if sn == 0:
            return None
        left = bool(fn & 1) or fn == sn
        sides.append((c, left))
        if left:
            while not fn & 1 and fn != 0:
                fn >>= 1
                sn >>= 1
        fn >>= 1
        sn >>= 1
    return sides if sn == 0 else None


def verify_inclusion(index: int, size: int, leaf: bytes, path: Sequence[bytes], root: bytes) -> bool:
    """2.1.3.2: does `path` prove leaf hash `leaf` at `index` in the tree of `size` with `root`?"""
    if not 0 <= index < size:
        return False
    sides = _sides(index, size - 1, path)
    if sides is None:
        return False
    r = leaf
    for c, left in sides:
        r = node_hash(c, r) if left else node_hash(r, c)
    return r == root


def verify_consistency(old: int, new: int, old_root: bytes, new_root: bytes, proof: Sequence[bytes]) -> bool:
    """2.1.4.2: is the tree of size `new` with `new_root` an extension of the one of `old`?"""
    if not 0 <= old <= new:
        return False
    if old == new:
        return not proof and old_root == new_root
    if old == 0:
        return not proof  # every tree extends the empty tree
    if not proof:
        return False
    path = list(proof)
    if old & (old - 1) == 0:  # an exact power of two: the old root is the first node
        path.insert(0, old_root)
    fn, sn = old - 1, new - 1
    while fn & 1:
        fn >>= 1
        sn >>= 1
    sides = _sides(fn, sn, path[1:])
    if sides is None:
        return False
    fr = sr = path[0]
    for c, left in sides:
        if left:
            fr = node_hash(c, fr)
            sr = node_hash(c, sr)
        else:
            sr = node_hash(sr, c)
    return fr == old_root and sr == new_root


def consistency_proof_from(old: Frontier, new_leaves: Sequence[bytes]) -> list[bytes]:
    """PROOF(m, D[n]) from the old tree's frontier and the leaf hashes added since: O(n - m + log n).

    Every node of such a proof either lies left of m, and is then one of the old tree's
    perfect subtrees (its frontier), or lies wholly among the new leaves."""
    m, n = old.size, old.size + len(new_leaves)
    spans, start = {}, 0
    for size_, h in zip(old._sizes, old.hashes):
        spans[(start, start + size_)] = h
        start += size_
    out = []
    for a, b in consistency_ranges(m, n):
        if b <= m:
            out.append(spans[(a, b)])
        else:
            out.append(root_hash(new_leaves[a - m:b - m]))
    return out
