"""`authn import dca1000`: a simulated scene written as a TI DCA1000 raw capture (the test
writer follows TI's documented layout, tests/importers/capture.py) comes back as the same
recording, features and decision; every malformed capture or config exits 2 in one line."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from signatures.features import FEATURE_NAMES, extract
from signatures.importers.dca1000 import deinterleave
from signatures.importers.dwell import analytic_half_rate
from signatures.recording import read_recording, write_recording
from tests.importers.capture import quantise, raw_words, sdk_cfg, write_capture
from tests.importers.conftest import check_json, site_args

#: Features of the imported capture equal the original's to this (relative or absolute), except
#: the absolute level peak_amplitude_db, which moves by exactly the ADC scaling (within 0.01 dB).
FEATURE_RTOL = FEATURE_ATOL = 1e-3


def _features_match(original, imported, scale: float) -> None:
    a, b = extract(original).as_array(), extract(imported).as_array()
    for name, x, y in zip(FEATURE_NAMES, a, b):
        if name == "peak_amplitude_db":
            assert y - x == pytest.approx(20 * math.log10(scale), abs=0.01)
        else:
            assert y == pytest.approx(x, rel=FEATURE_RTOL, abs=FEATURE_ATOL), name


@pytest.fixture(scope="module")
def two_lane_capture(scene_rec, tmp_path_factory):
    """The scene on RX 3 of RX {1, 3} (RX 1: other noise), 2 LVDS lanes, complex, three
    back-to-back frames of 200 loops, split over two files mid-frame."""
    root = tmp_path_factory.mktemp("dca")
    q, scale = quantise(scene_rec.iq, 0.0)
    cube = np.zeros((600, 2, 80), complex)
    cube[:, 1, :] = q
    cube[:, 0, :] = np.round(np.random.default_rng(1).normal(scale=300, size=(600, 80)))
    files = write_capture(root / "cap.bin", raw_words(cube, 2, True), split_at=100_002)
    cfg = root / "profile.cfg"
    cfg.write_text(sdk_cfg(scene_rec.config, 80, loops=200, frames=3, frame_period_s=200 * scene_rec.config.pri_s,
                           rx_mask=0b1010))
    return root, files, cfg, q, scale


def test_round_trip_same_recording_features_and_decision(scene_rec, two_lane_capture, registry_db, cli) -> None:
    root, files, cfg, q, scale = two_lane_capture
    code, out, err = cli("import", "dca1000", *map(str, files), "--config", str(cfg), "--rx", "3",
                         "--frames-per-dwell", "3", *site_args(scene_rec), "--out", str(root / "imported.h5"))
    assert code == 0, err
    assert "600x80" in out
    back = read_recording(root / "imported.h5")
    assert back.domain == "if" and back.remote_id is None
    assert back.start_time == scene_rec.start_time and back.site == scene_rec.site
    for name in ("carrier_hz", "bandwidth_hz", "ramp_s", "pri_s", "sample_rate_hz", "range_offset_m"):
        assert getattr(back.config, name) == pytest.approx(getattr(scene_rec.config, name), rel=1e-9), name
    assert np.array_equal(back.iq, q.astype(np.complex64))  # bit-exact samples of the selected RX
    _features_match(scene_rec, back, scale)
    original = write_recording(scene_rec, root / "original.h5")
    code_a, a = check_json(cli, registry_db, original)
    code_b, b = check_json(cli, registry_db, root / "imported.h5")
    # the same decision either way; for this unsigned single dwell at the default targets: inconclusive
    assert code_a == 4 and a["decision"] == "inconclusive" and "radar-inconclusive" in a["reasons"]
    assert (code_b, b["decision"], b["reasons"]) == (code_a, a["decision"], a["reasons"])
    assert b["radar"]["model"] == a["radar"]["model"] and b["radar"]["range_m"] == pytest.approx(40.0, abs=1.0)


def test_json_config_gives_the_same_waveform_and_frame(scene_rec, two_lane_capture, cli) -> None:
    root, files, _, q, _ = two_lane_capture
    c = scene_rec.config
    doc = {"profiles": [{"profile_id": 0, "start_freq_ghz": c.carrier_hz / 1e9, "idle_time_us": 0.0,
                         "adc_start_time_us": 0.0, "ramp_end_time_us": c.ramp_s * 1e6,
                         "freq_slope_mhz_per_us": c.slope_hz_per_s / 1e12, "num_adc_samples": 80,
                         "dig_out_sample_rate_ksps": c.sample_rate_hz / 1e3}],
           "chirps": [{"start_idx": 0, "end_idx": 0, "tx_enable": 1}],
           "frame": {"chirp_start_idx": 0, "chirp_end_idx": 0, "num_loops": 200, "num_frames": 3,
                     "frame_periodicity_ms": 200 * c.pri_s * 1e3},
           "channels": {"rx_enable": 10, "tx_enable": 1}, "adc": {"bits": 16, "output": "complex1x"}}
    (root / "profile.json").write_text(json.dumps(doc))
    code, _, err = cli("import", "dca1000", *map(str, files), "--config", str(root / "profile.json"), "--rx", "3",
                       "--frame", "1", *site_args(scene_rec), "--out", str(root / "frame1.h5"))
    assert code == 0, err
    one = read_recording(root / "frame1.h5")
    for name in ("carrier_hz", "bandwidth_hz", "ramp_s", "pri_s", "sample_rate_hz"):
        assert getattr(one.config, name) == pytest.approx(getattr(c, name), rel=1e-9), name
    assert np.array_equal(one.iq, q[200:400].astype(np.complex64))
    assert (one.start_time - scene_rec.start_time).total_seconds() == pytest.approx(200 * c.pri_s, abs=1e-6)


def test_every_frame_is_a_dwell_in_a_directory(scene_rec, two_lane_capture, cli) -> None:
    root, files, cfg, _, _ = two_lane_capture
    code, out, err = cli("import", "dca1000", *map(str, files), "--config", str(cfg), "--rx", "1",
                         *site_args(scene_rec), "--out", str(root / "frames"))
    assert code == 0, err
    names = sorted(p.name for p in (root / "frames").iterdir())
    assert names == ["frame_000000.h5", "frame_000001.h5", "frame_000002.h5"]
    recs = [read_recording(root / "frames" / n) for n in names]
    gaps = [(b.start_time - a.start_time).total_seconds() for a, b in zip(recs, recs[1:])]
    assert gaps == pytest.approx([200 * scene_rec.config.pri_s] * 2, abs=1e-6)
    assert all(r.n_chirps == 200 and r.n_samples == 80 for r in recs)


def test_four_lanes_tdm_and_real_adc(scene_rec, tmp_path: Path, cli) -> None:
    """4 lanes (lane r = RX r, disabled lanes zero), two TX chirps per loop (--tx 1 keeps the
    second: PRI = two chirp periods), real ADC samples made complex at half the rate."""
    c = scene_rec.config.replace(pri_s=2 * scene_rec.config.pri_s)
    z = scene_rec.iq[:64].astype(np.complex128)
    n = z.shape[1]
    up = np.zeros((64, 2 * n), complex)
    up[:, :n] = np.fft.fft(z, axis=1)
    real = 2 * np.fft.ifft(up, axis=1).real  # band-limited real IF at twice the rate: its analytic signal is 2x z
    q, scale = quantise(real + 0j, 0.0)
    cube = np.zeros((128, 4, 2 * n))
    cube[1::2, 2, :] = q.real  # TX 1 chirps, RX 2
    cube[0::2, 2, :] = 7.0  # TX 0 chirps: a constant the selection must drop
    path = tmp_path / "cap.bin"
    write_capture(path, raw_words(cube.astype(complex), 4, False))
    cfg = tmp_path / "p.cfg"
    cfg.write_text(sdk_cfg(c, n, loops=64, frames=1, frame_period_s=0.1, rx_mask=0b0100, tx_masks=(1, 2), real=True))
    code, _, err = cli("import", "dca1000", str(path), "--config", str(cfg), "--lanes", "4", "--tx", "1",
                       *site_args(scene_rec), "--out", str(tmp_path / "r.h5"))
    assert code == 0, err
    back = read_recording(tmp_path / "r.h5")
    assert back.config.pri_s == pytest.approx(c.pri_s, rel=1e-9)
    assert back.config.sample_rate_hz == pytest.approx(c.sample_rate_hz, rel=1e-9)
    assert back.config.bandwidth_hz == pytest.approx(c.bandwidth_hz, rel=1e-9)
    expected = analytic_half_rate(q.real)
    assert np.allclose(back.iq, expected, atol=1e-3 * np.abs(expected).max())
    # every second sample of 2x z, scaled: z itself but for the DC's imaginary part (a real IF has none)
    scaled = z * scale
    dc = 1j * np.mean(scaled, axis=1, keepdims=True).imag
    assert np.allclose(back.iq, scaled - dc, atol=1e-3 * np.abs(scaled).max())


@settings(max_examples=60, deadline=None)
@given(lanes=st.sampled_from([2, 4]), complex_=st.booleans(), n_chirps=st.integers(1, 5),
       n_samples=st.integers(1, 9).map(lambda k: 2 * k), n_rx=st.integers(1, 4), seed=st.integers(0, 2**16))
def test_deinterleave_inverts_the_documented_layout(lanes, complex_, n_chirps, n_samples, n_rx, seed) -> None:
    slots = 4 if lanes == 4 else n_rx
    rng = np.random.default_rng(seed)
    cube = rng.integers(-32768, 32767, size=(n_chirps, slots, n_samples)).astype(complex)
    if complex_:
        cube += 1j * rng.integers(-32768, 32767, size=cube.shape)
    back = deinterleave(raw_words(cube, lanes, complex_), n_chirps, slots, n_samples, lanes, complex_)
    assert back.shape == cube.shape
    assert np.array_equal(back, cube if complex_ else cube.real)


# --- bad input: one line, exit 2 --------------------------------------------------------

def _args(root: Path, files: list[Path], cfg: Path, rec, *extra: str) -> list[str]:
    return ["import", "dca1000", *map(str, files), "--config", str(cfg), *site_args(rec),
            "--out", str(root / "bad_out"), *extra]


CFG_EDITS = {
    "no frameCfg": (lambda t: "\n".join(ln for ln in t.splitlines() if not ln.startswith("frameCfg")),
                    "missing frameCfg"),
    "short profileCfg": (lambda t: t.replace("profileCfg 0", "profileCfg 0 77 1\n%", 1), "profileCfg: expected 14"),
    "not a number": (lambda t: t.replace("channelCfg 10", "channelCfg ten"), "not a number"),
    "advanced frames": (lambda t: t + "advFrameCfg 1 0 0 1 0\n", "advFrameCfg"),
    "BPM enabled": (lambda t: t.replace("bpmCfg -1 0 0 1", "bpmCfg -1 1 0 1"), "BPM"),
    "undefined chirp": (lambda t: t.replace("frameCfg 0 0", "frameCfg 0 1"), "chirp 1 of the frame"),
    "adc past ramp end": (lambda t: t.replace("adcCfg 2 1", "adcCfg 2 1\n%"), None),
}


@pytest.mark.parametrize("case", sorted(CFG_EDITS))
def test_bad_config_is_one_line(scene_rec, two_lane_capture, tmp_path: Path, cli, case: str) -> None:
    root, files, cfg, _, _ = two_lane_capture
    edit, expected = CFG_EDITS[case]
    if expected is None:  # ADC sampling longer than the ramp: rampEnd shortened
        text = cfg.read_text()
        parts = [ln.split() for ln in text.splitlines()]
        line = next(p for p in parts if p and p[0] == "profileCfg")
        line[5] = repr(float(line[5]) * 0.5)
        text = "\n".join(" ".join(p) for p in parts)
        expected = "exceeds the ramp end time"
    else:
        text = edit(cfg.read_text())
    bad = tmp_path / "bad.cfg"
    bad.write_text(text)
    code, _, err = cli(*_args(tmp_path, files, bad, scene_rec, "--rx", "3", "--frames-per-dwell", "3"))
    assert code == 2 and expected in err and err.count("\n") == 1, err


def test_bad_json_config_is_one_line(scene_rec, two_lane_capture, tmp_path: Path, cli) -> None:
    root, files, _, _, _ = two_lane_capture
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"profiles": [], "chirps": [], "frame": {}, "channels": {}, "extra": 1}))
    code, _, err = cli(*_args(tmp_path, files, bad, scene_rec))
    assert code == 2 and "bad.json" in err and err.count("\n") == 1, err
    bad.write_text("{not json")
    code, _, err = cli(*_args(tmp_path, files, bad, scene_rec))
    assert code == 2 and "not valid JSON" in err and err.count("\n") == 1, err


@pytest.mark.parametrize("case", ["truncated", "odd bytes", "extra frame", "rx off", "tx absent", "frame range",
                                  "frames with gaps", "one file for three dwells", "lanes"])
def test_bad_capture_or_selection_is_one_line(scene_rec, two_lane_capture, tmp_path: Path, cli, case: str) -> None:
    root, files, cfg, _, _ = two_lane_capture
    data = b"".join(f.read_bytes() for f in files)
    raw = tmp_path / "cap.bin"
    raw.write_bytes(data)
    extra = ["--rx", "3"]
    expected = {"truncated": "not a whole number of frames", "odd bytes": "not whole int16 words",
                "extra frame": "frameCfg says 3", "rx off": "RX 0 is not enabled", "tx absent": "TX 1",
                "frame range": "frames 0..2", "frames with gaps": "without a gap", "lanes": "--lanes",
                "one file for three dwells": "give a directory"}[case]
    if case == "truncated":
        raw.write_bytes(data[:-4])
    elif case == "odd bytes":
        raw.write_bytes(data + b"\0")
    elif case == "extra frame":
        raw.write_bytes(data + data[: len(data) // 3])
    elif case == "rx off":
        extra = ["--rx", "0"]
    elif case == "tx absent":
        extra += ["--tx", "1"]
    elif case == "frame range":
        extra += ["--frame", "3"]
    elif case == "frames with gaps":
        slow = tmp_path / "slow.cfg"
        slow.write_text(cfg.read_text().replace("frameCfg 0 0 200 3 ", "frameCfg 0 0 200 3 100.0 1 0\n% "))
        cfg = slow
        extra += ["--frames-per-dwell", "3"]
    elif case == "lanes":
        extra += ["--lanes", "3"]
    args = _args(tmp_path, [raw], cfg, scene_rec, *extra)
    if case == "one file for three dwells":
        args[args.index("--out") + 1] = str(tmp_path / "x.h5")
    code, _, err = cli(*args)
    assert code == 2 and expected in err and err.count("\n") == 1, err
    assert not (tmp_path / "x.h5").exists()
