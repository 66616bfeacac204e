"""RFC 9162 Merkle tree: known vectors, and brute-force cross-checks against the recursive definition.

Known vectors: the Certificate Transparency reference data as published in
transparency-dev/merkle (testonly/constants.go: leaf inputs, node and root hashes;
proof/verify_test.go: inclusion and consistency proofs; both carried over from the
C++ certificate-transparency merkle_tree_test.cc). Their leaf indices are 1-based.
"""

from __future__ import annotations

import hashlib

import pytest

from authn.audit import merkle

LEAF_INPUTS = [bytes.fromhex(h) for h in ["", "00", "10", "2021", "3031", "40414243", "5051525354555657",
                                           "606162636465666768696a6b6c6d6e6f"]]
ROOTS = [
    "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855",
    "6e340b9cffb37a989ca544e6bb780a2c78901d3fb33738768511a30617afa01d",
    "fac54203e7cc696cf0dfcb42c92a1d9dbaf70ad9e621f4bd8d98662f00e3c125",
    "aeb6bcfe274b70a14fb067a5e5578264db0fa9b51af5e0ba159158f329e06e77",
    "d37ee418976dd95753c1c73862b9398fa2a2cf9b4ff0fdfe8b30cd95209614b7",
    "4e3bbb1f7b478dcfe71fb631631519a3bca12c9aefca1612bfce4c13a86264d4",
    "76e67dadbcdf1e10e1b74ddc608abd2f98dfb16fbce75277b5232a127f2087ef",
    "ddb89be403809e325750d3d263cd78929c2942b7942a34b77e122c9594a74c8c",
    "5dc9da79a70659a9ad559cb701ded9a2ab9d823aad2f4960cfe370eff4604328",
]
NODES = {  # the reference data's proof nodes, by the leaves (0-based, end exclusive) they cover
    (0, 1): "6e340b9cffb37a989ca544e6bb780a2c78901d3fb33738768511a30617afa01d",
    (0, 2): "fac54203e7cc696cf0dfcb42c92a1d9dbaf70ad9e621f4bd8d98662f00e3c125",
    (0, 4): "d37ee418976dd95753c1c73862b9398fa2a2cf9b4ff0fdfe8b30cd95209614b7",
    (1, 2): "96a296d224f285c67bee93c30f8a309157f0daa35dc5b87e410b78630a09cfc7",
    (2, 4): "5f083f0a1a33ca076a95279832580db3e0ef4584bdff1f54c8a360f50de3031e",
    (4, 5): "bc1a0643b12e4d2d7c77918f44e0f4f79a838b6cf9ec5b5c283e1f4d88599e6b",
    (4, 6): "0ebc5d3437fbe2db158b9f126a1d118e308181031d0a949f8dededebc558ef6a",
    (4, 8): "6b47aaf29ee3c2af9af889bc1fb9254dabd31177f16232dd6aab035ca39bf6e4",
    (6, 7): "b08693ec2e721597130641e8211e7eedccb4c26413963eee6c1e2ed16ffb1a5f",
    (6, 8): "ca854ea128ed050b41b35ffc1b87b8eb2bde461e9e3b5596ece6b9d5975a0ae0",
}
INCLUSION = [  # (1-based leaf, tree size, path as NODES keys)
    (1, 1, []),
    (1, 8, [(1, 2), (2, 4), (4, 8)]),
    (6, 8, [(4, 5), (6, 8), (0, 4)]),
    (3, 3, [(0, 2)]),
    (2, 5, [(0, 1), (2, 4), (4, 5)]),
]
CONSISTENCY = [  # (old size, new size, proof as NODES keys)
    (1, 1, []),
    (1, 8, [(1, 2), (2, 4), (4, 8)]),
    (6, 8, [(4, 6), (6, 8), (0, 4)]),
    (2, 5, [(2, 4), (4, 5)]),
    (6, 7, [(4, 6), (6, 7), (0, 4)]),
]
LEAVES = [merkle.leaf_hash(d) for d in LEAF_INPUTS]


def _mth(leaves: list[bytes]) -> bytes:
    """The recursive definition of RFC 9162 2.1.1, verbatim (the reference for the fast paths)."""
    n = len(leaves)
    if n == 0:
        return hashlib.sha256(b"").digest()
    if n == 1:
        return leaves[0]
    k = 1 << ((n - 1).bit_length() - 1)
    return merkle.node_hash(_mth(leaves[:k]), _mth(leaves[k:]))


def _h(keys: list[tuple[int, int]]) -> list[bytes]:
    return [bytes.fromhex(NODES[k]) for k in keys]


def test_reference_nodes_are_the_subtrees_they_name() -> None:
    for (a, b), want in NODES.items():
        assert _mth(LEAVES[a:b]).hex() == want


def test_known_roots() -> None:
    for n, want in enumerate(ROOTS):
        assert merkle.root_hash(LEAVES[:n]).hex() == want


@pytest.mark.parametrize("leaf,size,path", INCLUSION)
def test_known_inclusion_proofs(leaf: int, size: int, path: list[str]) -> None:
    assert merkle.inclusion_proof(LEAVES[:size], leaf - 1) == _h(path)
    assert merkle.verify_inclusion(leaf - 1, size, LEAVES[leaf - 1], _h(path), bytes.fromhex(ROOTS[size]))


@pytest.mark.parametrize("old,new,proof", CONSISTENCY)
def test_known_consistency_proofs(old: int, new: int, proof: list[str]) -> None:
    assert merkle.consistency_proof(LEAVES[:new], old) == _h(proof)
    assert merkle.verify_consistency(old, new, bytes.fromhex(ROOTS[old]), bytes.fromhex(ROOTS[new]), _h(proof))


N = 64
MANY = [merkle.leaf_hash(i.to_bytes(2, "big")) for i in range(N)]
MTH = [_mth(MANY[:n]) for n in range(N + 1)]


def test_frontier_and_collector_roots_match_the_definition() -> None:
    f = merkle.Frontier()
    c = merkle.RangeCollector(root_sizes=range(N + 1))
    for n in range(1, N + 1):
        f.push(MANY[n - 1])
        c.push(MANY[n - 1])
        assert f.root() == MTH[n]
        assert merkle.Frontier(n, f.hashes).root() == MTH[n]  # persisted and reloaded
    assert all(c.roots[n] == MTH[n] for n in range(1, N + 1))


def test_every_inclusion_proof_up_to_64() -> None:
    bad = merkle.node_hash(b"x", b"y")
    for n in range(1, N + 1):
        for i in range(n):
            path = merkle.inclusion_proof(MANY[:n], i)
            assert merkle.verify_inclusion(i, n, MANY[i], path, MTH[n]), (i, n)
            assert not merkle.verify_inclusion(i, n, bad, path, MTH[n])
            assert not merkle.verify_inclusion(i, n, MANY[i], path, bad)
            assert not merkle.verify_inclusion(i, n, MANY[i], path + [bad], MTH[n])
            if n > 1:
                assert not merkle.verify_inclusion((i + 1) % n, n, MANY[i], path, MTH[n])
                assert not merkle.verify_inclusion(i, n, MANY[i], path[:-1], MTH[n])
                for j in range(len(path)):
                    altered = path[:j] + [bad] + path[j + 1:]
                    assert not merkle.verify_inclusion(i, n, MANY[i], altered, MTH[n])


def test_every_consistency_proof_up_to_64() -> None:
    bad = merkle.node_hash(b"x", b"y")
    for n in range(0, N + 1):
        for m in range(0, n + 1):
            proof = merkle.consistency_proof(MANY[:n], m)
            assert merkle.verify_consistency(m, n, MTH[m], MTH[n], proof), (m, n)
            if 0 < m < n:
                assert not merkle.verify_consistency(m, n, bad, MTH[n], proof)
                assert not merkle.verify_consistency(m, n, MTH[m], bad, proof)
                assert not merkle.verify_consistency(m, n, MTH[m], MTH[n], proof[:-1])
                for j in range(len(proof)):
                    altered = proof[:j] + [bad] + proof[j + 1:]
                    assert not merkle.verify_consistency(m, n, MTH[m], MTH[n], altered)
            if 0 < m < n:  # a tree whose first m leaves differ is not an extension
                other = [bad] + MANY[1:n]
                assert not merkle.verify_consistency(m, n, MTH[m], _mth(other),
                                                     merkle.consistency_proof(other, m))


def test_streaming_collector_gives_the_same_proofs() -> None:
    for n in range(1, N + 1):
        wanted = {r for m in range(n + 1) for r in merkle.consistency_ranges(m, n)}
        wanted |= {r for i in range(n) for r in merkle.inclusion_ranges(i, n)}
        c = merkle.RangeCollector(wanted, root_sizes=range(n + 1))
        for h in MANY[:n]:
            c.push(h)
        for r in wanted:
            assert c.hashes[r] == _mth(MANY[r[0]:r[1]]), (r, n)
        assert c.root() == MTH[n]
