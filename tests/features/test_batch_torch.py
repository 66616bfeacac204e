"""The torch cube stage (`signatures.dsp.torch_cube`, `extract_batch(..., device=...)`) gives the
numpy path's results to float32 rounding: same detection, gate and counts, every feature within
REL of max(|value|, 1) (the batch tests' `assert_same`; measured: <= 2.4e-6 on these returns), the
CNN patch within 1e-5; its cube-stage arrays within CUBE_REL of their row's largest value."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch", reason="torch is not installed (the cnn extra: pip install -e '.[cnn]')")

from signatures.dsp import extraction as bf  # noqa: E402
from signatures.dsp import torch_cube  # noqa: E402
from signatures.sim.domain import as_recorded  # noqa: E402
from signatures.errors import SignaturesError  # noqa: E402

from .test_batch_features import assert_same, drawn_fixture  # noqa: E402

CUBE_REL = 1e-5
NO_GPU = "no CUDA GPU on this machine (or torch is a CPU build): the CUDA path is untested here"


paper = drawn_fixture("paper", 24)
wide = drawn_fixture("wide", 4)


def _features_match(drawn, device: str) -> None:
    config = drawn[0][1].config
    iq = np.stack([r.iq for _, r in drawn])
    ref = bf.extract_batch(iq, config)
    got = bf.extract_batch(iq, config, device=device)
    assert len(got) == len(ref)
    for b, (r, g) in enumerate(zip(ref, got)):
        scene = drawn[b][0]
        assert_same(r, g, f"{device} row {b} ({scene.label}, {scene.snr_db:.0f} dB)")


@pytest.mark.parametrize("preset", ["paper", "wide"])
def test_cpu_device_features_equal_the_numpy_path(request, preset, monkeypatch):
    calls = []
    inner = torch_cube.range_spectra
    monkeypatch.setattr(torch_cube, "range_spectra", lambda iq, *a: calls.append(len(iq)) or inner(iq, *a))
    _features_match(request.getfixturevalue(preset), "cpu")
    assert sum(calls) == len(request.getfixturevalue(preset))  # every row's cube went through torch


@pytest.mark.skipif(not torch.cuda.is_available(), reason=NO_GPU)
@pytest.mark.parametrize("preset", ["paper", "wide"])
def test_cuda_device_features_equal_the_numpy_path(request, preset):
    _features_match(request.getfixturevalue(preset), "cuda")


@pytest.mark.parametrize("options", [dict(), dict(suppress=False), dict(domain="range")], ids=str)
def test_cube_stage_equals_the_numpy_cube_stage(paper, options):
    """Spectra of the gate and patch columns, profile and mu to float32 rounding; scale and
    all-zero flags exactly; rows near and far from unit scale and an all-zero row included."""
    suppress, domain = options.get("suppress", True), options.get("domain", "if")
    iq = np.stack([r.iq if domain == "if" else as_recorded(r, domain).iq for _, r in paper[:8]])
    iq[2] = 0
    iq[3] *= np.float32(2.0 ** -19)
    far = iq.copy()
    far[5] *= np.float32(2.0 ** 40)
    for cube_iq in (iq, far):
        args = (cube_iq, [None] * len(cube_iq), 5, suppress, domain, list(range(len(cube_iq))), "scipy")
        ref = bf._cube_stage(*args)
        got = bf._cube_stage(*args, torch_cube.resolve("cpu"))
        for name in ("log2_scale", "zero", "detected", "peak_bin", "gate_lo", "patch_lo"):
            assert np.array_equal(getattr(got, name), getattr(ref, name)), name
        for name in ("profile", "mu", "slow", "patch_cols"):
            r, g = getattr(ref, name), getattr(got, name)
            scale = np.abs(r.reshape(len(r), -1)).max(axis=1)
            err = np.abs(g - r).reshape(len(r), -1).max(axis=1)
            assert np.all(err <= CUBE_REL * scale), f"{name}: {err / np.maximum(scale, 1e-30)}"


def test_device_names(paper, monkeypatch):
    config = paper[0][1].config
    iq = np.stack([r.iq for _, r in paper[:4]])
    assert torch_cube.resolve("cpu") == torch.device("cpu")
    for bad in ("tpu", "cuda:x", "meta"):
        with pytest.raises(SignaturesError, match="unknown device"):
            bf.extract_batch(iq, config, device=bad)
    monkeypatch.setattr(torch.cuda, "is_available", lambda: False)
    assert torch_cube.resolve("auto") is None  # numpy, not torch's CPU
    with pytest.raises(SignaturesError, match="no CUDA GPU"):
        bf.extract_many([r for _, r in paper[:4]], device="cuda")
    calls = []
    monkeypatch.setattr(torch_cube, "range_spectra", lambda *a: calls.append(1))
    auto = bf.extract_batch(iq, config, device="auto")
    assert not calls  # 'auto' without CUDA never touched torch
    for b, res in enumerate(bf.extract_batch(iq, config)):
        assert np.array_equal(res.as_array(), auto[b].as_array())
