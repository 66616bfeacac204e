"""Optional CNN on the range-Doppler patch (training side; needs the `cnn` extra, torch).

Small on purpose (three 3x3 conv blocks, global average pooling, ~25 k weights):
it trains on CPU in well under a minute on a few thousand patches. The trained
network is exported to ONNX, so inference (signatures.classify.inference) never needs torch.
"""

from __future__ import annotations

import io
import warnings
from pathlib import Path

import numpy as np

_NOTICE_GIVEN = False


def torch_available() -> bool:
    """True when torch can be imported; otherwise warns once per process (CNN training skipped)."""
    global _NOTICE_GIVEN
    try:
        import torch  # noqa: F401
    except ImportError:
        if not _NOTICE_GIVEN:
            warnings.warn("torch is not installed: CNN training skipped, the ensemble works alone "
                          "(pip install 'uav-radar-authn[cnn]')", RuntimeWarning, stacklevel=2)
            _NOTICE_GIVEN = True
        return False
    return True


def _net(n_classes: int):  # -> torch.nn.Module
    from torch import nn

    def block(i: int, o: int) -> list:
        return [nn.Conv2d(i, o, 3, padding=1), nn.ReLU(), nn.MaxPool2d(2)]

    return nn.Sequential(*block(1, 16), *block(16, 32), nn.Conv2d(32, 48, 3, padding=1), nn.ReLU(),
                         nn.AdaptiveAvgPool2d(1), nn.Flatten(), nn.Linear(48, n_classes))


def train_cnn(rd: np.ndarray, y: np.ndarray, n_classes: int, seed: int, epochs: int = 12,
              batch: int = 64, progress: bool = False) -> tuple[object, float, float]:
    """Train on RD patches; returns (model, input mean, input std). Deterministic for a seed."""
    import torch

    torch.manual_seed(seed)
    torch.use_deterministic_algorithms(True)
    threads = torch.get_num_threads()
    torch.set_num_threads(1)  # bit-reproducible reductions
    try:
        mean, std = float(rd.mean()), float(rd.std() or 1.0)
        x = torch.from_numpy(((rd - mean) / std).astype(np.float32)[:, None])
        t = torch.from_numpy(y.astype(np.int64))
        model = _net(n_classes)
        opt = torch.optim.Adam(model.parameters(), lr=3e-3)
        gen = torch.Generator().manual_seed(seed)
        for epoch in range(epochs):
            model.train()
            perm = torch.randperm(len(x), generator=gen)
            for i in range(0, len(x), batch):
                idx = perm[i:i + batch]
                opt.zero_grad()
                loss = torch.nn.functional.cross_entropy(model(x[idx]), t[idx])
                loss.backward()
                opt.step()
            if progress:
                print(f"  cnn epoch {epoch + 1}/{epochs}: loss {float(loss):.3f}")
        model.eval()
        return model, mean, std
    finally:
        torch.set_num_threads(threads)


def export_cnn(model: object, shape: tuple[int, int], path: Path) -> None:
    """ONNX with input `rd` (N, 1, H, W) and output `logits` (legacy exporter: no onnxscript needed)."""
    import torch

    buf = io.BytesIO()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        torch.onnx.export(model, (torch.zeros(1, 1, *shape),), buf, dynamo=False, input_names=["rd"],
                          output_names=["logits"], dynamic_axes={"rd": {0: "n"}, "logits": {0: "n"}},
                          opset_version=17)
    path.write_bytes(buf.getvalue())
