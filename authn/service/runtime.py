"""What one worker process loads once and shares between requests: the Checker (policy,
database connection, classifiers), the role policy, the metrics. The Checker's DB-API
connection belongs to one thread, so every use of it runs on this runtime's single
executor thread (checks are CPU-bound under the GIL anyway; workers give parallelism). API keys
are looked up on the key store's own thread and connection."""

from __future__ import annotations

import asyncio
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Any, TypeVar

from authn.service.auth import RolePolicy
from authn.service.keystore import KeyStore
from authn.service.metrics import Metrics
from authn.service.settings import Settings

T = TypeVar("T")


@dataclass
class Runtime:
    settings: Settings
    checker: Any
    roles: RolePolicy
    metrics: Metrics
    executor: ThreadPoolExecutor = field(default_factory=lambda: ThreadPoolExecutor(1, "authn-checker"))
    started: float = field(default_factory=time.monotonic)
    models: list[str] = field(default_factory=list)
    keys: KeyStore | None = None

    @classmethod
    def load(cls, settings: Settings) -> "Runtime":
        from authn.check import Checker

        rt = cls(settings, None, RolePolicy(), Metrics())
        rt.checker = rt.executor.submit(Checker, settings.db_url, settings.policy_path).result()
        rt.models = rt.executor.submit(_warm_classifiers).result()
        rt.executor.submit(rt.checker.db.connection).result()  # opens (and migrates) the database now
        rt.keys = KeyStore(settings.db_url, rt.roles)
        return rt

    async def run(self, fn: Callable[[], T]) -> T:
        """Run `fn` on the checker's thread."""
        return await asyncio.get_running_loop().run_in_executor(self.executor, fn)

    def close(self) -> None:
        if self.keys is not None:
            self.keys.close()
        self.executor.submit(self.checker.db.close).result()
        self.executor.shutdown()


def _warm_classifiers() -> list[str]:
    """Load every shipped classifier now, so the first check of a waveform is not slow."""
    from signatures.classify.inference import PRESETS, load_classifier
    from signatures.errors import SignaturesError

    loaded = []
    for preset in PRESETS:
        try:
            load_classifier(preset)
        except SignaturesError:
            continue  # a preset without a shipped bundle is checked with --model only
        loaded.append(preset)
    return loaded
