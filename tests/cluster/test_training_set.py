"""`authn models train --cluster`: the training set's chunks run as Dask tasks and give the
same dataset, bit for bit, as generating it in one process."""

from __future__ import annotations

import numpy as np
from distributed import get_task_stream

from signatures.train.dataset import DatasetSpec, _ARRAYS, chunks_on, generate
from signatures.profiles import shipped_profiles


def test_chunks_on_the_cluster_give_the_same_dataset(client) -> None:
    spec = DatasetSpec(preset="paper", profiles=tuple(shipped_profiles().values()), split="train", n=7, seed=3)
    local = generate(spec, workers=1, cache=False)
    with get_task_stream(client) as tasks, chunks_on(client.get_executor()):
        remote = generate(spec, chunk=2, cache=False)  # 4 chunks, as tasks on 2 workers
    assert len(tasks.data) == 4
    for name in set(_ARRAYS) - {"feature_ms"}:  # feature_ms is a wall time
        a, b = getattr(local, name), getattr(remote, name)
        assert a.dtype == b.dtype and np.array_equal(a, b), name
    assert remote.classes == local.classes and remote.feature_names == local.feature_names
    assert len(set(local.y)) > 1  # several classes: the chunks really differ
