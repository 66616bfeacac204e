"""The cube stage of `signatures.dsp.extraction` in torch, on a CPU or CUDA device.

Why: the cube stage (scaling, clutter suppression, range FFT, range profile) is the only part
of a batch that touches every sample; on a GPU it runs at memory speed while the slow-time
stage, which only sees each row's few gate columns, stays in numpy. Only the profile (B x bins),
mu and the kept gate and patch columns come back to the host; detection and gating run on the
profile in numpy, exactly as on the numpy path.

Same arithmetic as the scipy cube stage (`extraction._spectra32`: complex64 data minus its
slow-time mean, times the float32 window with the exact power-of-two scale riding on it,
complex64 FFT), but torch's reductions and FFT round differently: the outputs equal the numpy
path's to float32 rounding, not bit for bit (tests/features/test_batch_torch.py).

Imported only when `extract_batch`/`extract_many` get a `device` (torch is the optional `cnn`
extra).
"""

from __future__ import annotations

import numpy as np
import torch

from signatures.dsp import rd
from signatures.dsp.cube_scale import prepared
from signatures.errors import SignaturesError

__all__ = ["columns", "range_spectra", "resolve"]


def resolve(device: str) -> torch.device | None:
    """The torch device a `device` argument names: 'auto' is CUDA when available, else None
    (the numpy path); 'cpu', 'cuda' or 'cuda:N' otherwise. Anything else, or CUDA without a GPU,
    raises `SignaturesError`."""
    if device == "auto":
        return torch.device("cuda") if torch.cuda.is_available() else None
    try:
        dev = torch.device(device)
    except (RuntimeError, TypeError):
        raise SignaturesError(f"unknown device {device!r} (known: auto, cpu, cuda, cuda:N)") from None
    if dev.type not in ("cpu", "cuda"):
        raise SignaturesError(f"unknown device {device!r} (known: auto, cpu, cuda, cuda:N)")
    if dev.type == "cuda" and not torch.cuda.is_available():
        raise SignaturesError(f"device {device!r}: no CUDA GPU here (or torch is a CPU build)")
    return dev


def range_spectra(iq: np.ndarray, suppress: bool, domain: str, labels: list[int], device: torch.device
                  ) -> tuple[torch.Tensor, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The range spectra (`extraction._range_spectra`) of every row of `iq` (B, chirps, samples) on `device`:
    (complex64 spectra (B, chirps, bins) on the device, mu (B, bins) complex64, log2 scale,
    all-zero flag, range profile (B, bins) float32). A NaN or Inf raises naming its row."""
    x, scale, exponent, zero = prepared(iq, labels)  # one host pass: checks and exponents
    n_chirps, n_bins = x.shape[1:]
    if not x.flags.writeable:  # torch wants writable memory; the input itself is never written
        x = x.copy()
    data = torch.from_numpy(x).to(device)
    window = rd.hann(n_bins).astype(np.float32) if domain == "if" else np.ones(n_bins, np.float32)
    weight = torch.from_numpy(window * scale.astype(np.float32)).to(device)  # (B, 1, bins): exact products
    mean = data.mean(dim=1, keepdim=True)
    spectra = data - mean if suppress else data.clone()
    spectra.mul_(weight)
    mu = mean[:, 0] * weight[:, 0]
    if domain == "if":  # a range cube already is a range spectrum
        spectra = torch.fft.fft(spectra, dim=-1)
        mu = torch.fft.fft(mu, dim=-1)
    profile = torch.view_as_real(spectra).square().sum(dim=(1, 3)) / n_chirps
    return spectra, mu.cpu().numpy(), exponent, zero, profile.cpu().numpy()


def columns(spectra: torch.Tensor, lo: np.ndarray, size: int, out: np.ndarray) -> None:
    """spectra[b, :, lo[b]:lo[b] + size] of every row b, gathered on the device, into `out`."""
    idx = torch.from_numpy(lo[:, None] + np.arange(size)).to(spectra.device)
    picked = torch.gather(spectra, 2, idx[:, None, :].expand(-1, spectra.shape[1], -1))
    out[...] = picked.cpu().numpy()
