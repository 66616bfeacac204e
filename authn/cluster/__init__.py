"""Bulk work on a Dask distributed cluster (the optional `cluster` extra): `authn check
--cluster` re-checks an archive in partitions on workers, `authn models train --cluster`
simulates the training set there. Nothing here is imported unless `--cluster` is given.

`engine` connects (a local cluster or a scheduler address), `worker` is what runs on a
worker (no Dask import), `recheck` is the client side of a re-check. docs/cluster.md.
"""
