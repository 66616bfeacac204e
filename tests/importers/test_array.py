"""`authn import array` and the range/CW domains end to end: a simulated IF scene converted
with `to_domain`, saved as .npy/.mat, imported, checked. Range keeps the features, the
decision and the range evidence; CW runs, states that it measured no range, and without a
classifier for its waveform exits 2 with the "no classifier" error."""

from __future__ import annotations

import dataclasses
import json
from datetime import datetime, timezone
from pathlib import Path

import h5py
import numpy as np
import pytest
import scipy.io

from authn.scenario import Broadcast, simulate_flight
from signatures.sim.domain import cw_config, range_config, to_domain
from signatures.features import FEATURE_NAMES, extract
from signatures.profiles import shipped_profiles
from signatures.radar import get_preset
from signatures.recording import read_recording, write_recording
from signatures.sim.scene import Scene
from tests.importers.conftest import M300, check_json, site_args

#: Range-domain features equal the IF pipeline's to this (relative or absolute): the same range
#: spectrum, with the clutter mean removed after the FFT instead of before (float32 rounding).
FEATURE_RTOL = FEATURE_ATOL = 1e-3


@pytest.fixture(scope="module")
def flight():
    """The M300 at 40 m broadcasting its Remote ID (claim, position, velocity)."""
    scene = Scene(profile=shipped_profiles()["m300"], range_m=40.0, radial_speed_mps=3.0, snr_db=20.0)
    rec, _ = simulate_flight(scene, get_preset("paper"), 5, Broadcast(serial=M300), azimuth_deg=30.0,
                             range_offset_m=0.0, start_time=datetime.now(timezone.utc).replace(microsecond=0))
    return rec


def _as(rec, domain: str):
    c, n = rec.config, rec.n_samples
    config = (range_config(c.carrier_hz, c.pri_s, c.range_bin_m(n), c.range_offset_m, n) if domain == "range"
              else cw_config(c.carrier_hz, c.pri_s))
    return dataclasses.replace(rec, iq=to_domain(rec.iq, c, domain), config=config, domain=domain, simulation=None)


@pytest.fixture
def paper_classifier(monkeypatch):
    """Serve the shipped paper classifier for any waveform. For a range-domain file with the
    paper's numbers that is exact (its features are the IF pipeline's); which bundle the
    product picks for non-IF domains by itself belongs to the classifier-selection code."""
    from signatures.classify import inference

    clf = inference.load_classifier("paper")
    monkeypatch.setattr(inference, "classifier_for", lambda *a, **k: clf)
    monkeypatch.setattr(inference, "match_preset", lambda *a, **k: "paper", raising=False)


def _import(cli, path: Path, rec, domain: str, out: Path, *extra: str) -> tuple[int, str, str]:
    return cli("import", "array", str(path), "--domain", domain, "--carrier-hz", repr(rec.config.carrier_hz),
               *site_args(rec), "--out", str(out), *extra)


def test_to_domain_is_pure_and_exact(scene_rec) -> None:
    before = scene_rec.iq.copy()
    rng = to_domain(scene_rec.iq, scene_rec.config, "range")
    cw = to_domain(scene_rec.iq, scene_rec.config, "cw")
    assert np.array_equal(scene_rec.iq, before)
    assert to_domain(scene_rec.iq, scene_rec.config, "if") is scene_rec.iq
    from signatures.dsp import rd

    assert np.array_equal(rng, rd.range_fft(scene_rec.iq, suppress_clutter=False))
    assert cw.shape == (scene_rec.n_chirps, 1) and np.array_equal(cw[:, 0], scene_rec.iq[:, 0])
    c = range_config(77e9, 1e-4, 0.5, 20.0, 64)
    assert c.range_bin_m(64) == pytest.approx(0.5, rel=1e-12) and c.range_offset_m == 20.0
    assert cw_config(24e9, 1e-4).doppler_wavelength_m(1) == pytest.approx(299_792_458.0 / 24e9, rel=1e-12)


#: Features computed from the flash series (or its rate).
FLASH_DERIVED = {"flash_rate_hz", "flash_rate_std_hz", "rotor_rate_hz", "rotor_rate_std_hz", "rotor_count",
                 "rotor_count_std", "blade_length_m", "blade_length_std_m", "flash_score", "flash_count",
                 "flash_par_db", "cadence_peak_hz", "cadence_harmonic_ratio"}


def test_range_round_trip_features_decision_and_range_evidence(scene_rec, flight, registry_db, cli, tmp_path,
                                                                paper_classifier) -> None:
    c = scene_rec.config
    cube = to_domain(scene_rec.iq, c, "range")
    np.save(tmp_path / "range.npy", cube.T)  # stored as range bins x pulses, like the KTH/SAAB .mat files
    code, out, err = _import(cli, tmp_path / "range.npy", scene_rec, "range", tmp_path / "range.h5", "--transpose",
                             "--pri-s", repr(c.pri_s), "--range-bin-m", repr(c.range_bin_m(80)),
                             "--first-range-m", "0")
    assert code == 0 and "'range' dwell of 600x80" in out, err
    back = read_recording(tmp_path / "range.h5")
    assert back.domain == "range" and np.array_equal(back.iq, cube)
    for name in ("carrier_hz", "bandwidth_hz", "ramp_s", "pri_s", "sample_rate_hz", "range_offset_m"):
        assert getattr(back.config, name) == pytest.approx(getattr(c, name), rel=1e-9, abs=1e-9), name
    # a range cube has no fast time: its flash series comes from whole-chirp bins, an IF cube's from
    # sub-chirp windows (docs/features.md), so the flash-derived features may differ; the rest are equal
    from_if, from_range = extract(scene_rec).features, extract(back).features
    for name, x, y in zip(FEATURE_NAMES, from_if.as_array(), from_range.as_array()):
        if name not in FLASH_DERIVED:
            assert y == pytest.approx(x, rel=FEATURE_RTOL, abs=FEATURE_ATOL), name
    assert from_range.flash_rate_hz == pytest.approx(from_if.flash_rate_hz, rel=0.05)
    original = write_recording(scene_rec, tmp_path / "if.h5")
    code_a, a = check_json(cli, registry_db, original)
    code_b, b = check_json(cli, registry_db, tmp_path / "range.h5")
    # the same decision either way; for this unsigned single dwell at the default targets: inconclusive
    assert code_a == 4 and a["decision"] == "inconclusive" and "radar-inconclusive" in a["reasons"]
    assert (code_b, b["decision"], b["reasons"], b["radar"]["model"]) == \
        (code_a, a["decision"], a["reasons"], a["radar"]["model"])
    # with Remote ID: the range-domain file keeps its range evidence
    ranged = write_recording(_as(flight, "range"), tmp_path / "flight_range.h5")
    _, d = check_json(cli, registry_db, ranged)
    assert d["radar"]["range_m"] == pytest.approx(40.0, abs=1.0) and "range_evidence" not in d["radar"]
    assert d["kinematics"]["range_residual_m"] <= d["kinematics"]["range_tolerance_m"]
    assert "range-not-measured" not in d["reasons"]


def test_cw_import_and_check_state_no_range(flight, registry_db, cli, tmp_path, paper_classifier) -> None:
    cw = _as(flight, "cw")
    iq = cw.iq[:, 0]
    scipy.io.savemat(tmp_path / "cw.mat", {"I": iq.real.astype(np.float64), "Q": iq.imag.astype(np.float64)})
    code, out, err = _import(cli, tmp_path / "cw.mat", flight, "cw", tmp_path / "cw.h5", "--var", "I",
                             "--imag-var", "Q", "--sample-rate-hz", repr(1.0 / flight.config.pri_s))
    assert code == 0 and "'cw' dwell of 600x1" in out, err
    back = read_recording(tmp_path / "cw.h5")
    assert back.domain == "cw" and np.array_equal(back.iq, cw.iq.astype(np.complex128))
    assert back.config.pri_s == pytest.approx(flight.config.pri_s, rel=1e-12)
    feats = extract(back)
    assert np.all(np.isfinite(feats.as_array()))
    assert feats.features.range_m == feats.features.mean_range_m == feats.features.range_std_m == 0.0
    with_rid = write_recording(cw, tmp_path / "cw_rid.h5")  # the same samples with the drone's Remote ID
    code, out = check_json(cli, registry_db, with_rid)
    radar, kin = out["radar"], out["kinematics"]
    assert radar["range_m"] is None and radar["range_evidence"] == "not measured: CW recording"
    assert not radar["gated"]
    assert radar["model"] != "none", "the moving M300 is detected in CW"
    assert kin["range_residual_m"] is None and kin["range_tolerance_m"] is None
    assert kin["range_evidence"] == "not measured: CW recording"
    assert kin["radial_velocity_residual_mps"] <= kin["radial_velocity_tolerance_mps"]
    assert code == 1 and "range-not-measured" in out["reasons"] and "range-mismatch" not in out["reasons"]


def test_cw_without_a_classifier_exits_2(flight, registry_db, cli, tmp_path) -> None:
    path = write_recording(_as(flight, "cw"), tmp_path / "cw.h5")
    code, out, err = cli("--db", registry_db, "check", str(path), "--serial", M300)
    assert code == 2 and "no classifier for this waveform" in err and err.count("\n") == 1 and not out


def test_mat73_interleaved_npy_and_dwell_split(scene_rec, cli, tmp_path) -> None:
    c = scene_rec.config
    cube = to_domain(scene_rec.iq, c, "range").astype(np.complex128)
    path = tmp_path / "v73.mat"
    with h5py.File(path, "w", userblock_size=512) as f:  # what MATLAB's save -v7.3 writes
        data = np.empty(cube.T.shape, dtype=[("real", "<f8"), ("imag", "<f8")])
        data["real"], data["imag"] = cube.T.real, cube.T.imag  # column-major: HDF5 holds MATLAB's transpose
        f.create_dataset("X", data=data).attrs["MATLAB_class"] = np.bytes_(b"double")
    with path.open("r+b") as fh:
        fh.write(b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Mon Jun  2 10:00:00 2025 HDF5 schema 1.00 .")
    code, _, err = _import(cli, path, scene_rec, "range", tmp_path / "v73.h5", "--var", "X", "--pri-s",
                           repr(c.pri_s), "--range-bin-m", repr(c.range_bin_m(80)))
    assert code == 0, err
    assert np.array_equal(read_recording(tmp_path / "v73.h5").iq, cube)
    iq = to_domain(scene_rec.iq, c, "cw")[:, 0]
    inter = np.empty(2 * iq.size, np.int16)
    q = np.round(iq / np.abs(iq).max() * 3e4)
    inter[0::2], inter[1::2] = q.real, q.imag
    np.save(tmp_path / "cw.npy", inter)
    code, out, err = _import(cli, tmp_path / "cw.npy", scene_rec, "cw", tmp_path / "dwells", "--interleaved",
                             "--pri-s", repr(c.pri_s), "--pulses-per-dwell", "256")
    assert code == 0 and "2 'cw' dwells of 256x1" in out, err
    recs = [read_recording(tmp_path / "dwells" / f"dwell_{i:06d}.h5") for i in range(2)]
    assert np.array_equal(recs[1].iq[:, 0], q[256:512].astype(np.complex64))
    assert (recs[1].start_time - recs[0].start_time).total_seconds() == pytest.approx(256 * c.pri_s, abs=1e-6)


def _bad_inputs(tmp_path: Path, rec) -> dict[str, tuple[list[str], str]]:
    c = rec.config
    cube = to_domain(rec.iq, c, "range")
    np.save(tmp_path / "ok.npy", cube)
    np.save(tmp_path / "obj.npy", np.array([{"a": 1}], dtype=object), allow_pickle=True)
    np.save(tmp_path / "real.npy", np.abs(cube))
    nan = cube.copy()
    nan[3, 3] = np.nan
    np.save(tmp_path / "nan.npy", nan)
    np.savez(tmp_path / "two.npz", a=cube, b=cube)
    np.save(tmp_path / "cube3.npy", np.zeros((2, 3, 4), np.complex64))
    (tmp_path / "x.txt").write_text("1 2 3")
    scipy.io.savemat(tmp_path / "struct.mat", {"s": {"a": np.arange(3)}})
    rng = ["--pri-s", repr(c.pri_s), "--range-bin-m", "1.0"]
    return {
        "pickle": (["obj.npy", "range", *rng], "not a readable numpy file"),
        "magnitudes for range": (["real.npy", "range", *rng], "the samples are real"),
        "range without bin": (["ok.npy", "range", "--pri-s", "1e-4"], "needs --range-bin-m"),
        "cw given a bin": (["ok.npy", "cw", "--pri-s", "1e-4", "--range-bin-m", "1"], "cw"),
        "cw two rates": (["ok.npy", "cw", "--pri-s", "1e-4", "--sample-rate-hz", "1e4"], "one of --pri-s"),
        "unknown domain": (["ok.npy", "doppler", *rng], "--domain"),
        "NaN": (["nan.npy", "range", *rng], "NaN or Inf"),
        "npz without var": (["two.npz", "range", *rng], "name one with --var"),
        "absent var": (["two.npz", "range", *rng, "--var", "zz"], "has no variable 'zz'"),
        "axis order": (["ok.npy", "range", *rng, "--axis-order", "x,y"], "--axis-order"),
        "suffix": (["x.txt", "range", *rng], "expected a .npy"),
        "3-D": (["cube3.npy", "range", *rng], "expected a 2-D array"),
        "dwell longer than file": (["ok.npy", "range", *rng, "--pulses-per-dwell", "601"], "--pulses-per-dwell"),
        "struct": (["struct.mat", "range", *rng], "not a numeric array"),
        "pri below zero": (["ok.npy", "range", "--pri-s", "-1", "--range-bin-m", "1"], "--pri-s: must be a positive"),
    }


def test_bad_input_is_one_line_exit_2(scene_rec, cli, tmp_path) -> None:
    for case, (args, expected) in _bad_inputs(tmp_path, scene_rec).items():
        file, domain, *extra = args
        code, _, err = _import(cli, tmp_path / file, scene_rec, domain, tmp_path / f"{len(case)}.h5", *extra)
        assert code == 2 and expected in err and err.count("\n") == 1, (case, err)


def test_if_import_with_the_bundles_radar_config_matches_its_classifier(scene_rec, registry_db, cli,
                                                                         tmp_path) -> None:
    """`models list --json` prints a bundle's exact waveform; given to `import array
    --radar-config`, the imported IF file is served by that bundle (no "no classifier"), with
    the waveform's values to the bit and one dwell of the bundle's chirps."""
    code, out, err = cli("models", "list", "--json")
    assert code == 0, err
    paper = next(b for b in json.loads(out) if b["name"] == "paper")["waveform"]
    config = {k: v for k, v in paper.items() if k not in ("description", "key")}
    (tmp_path / "paper.json").write_text(json.dumps(config))
    np.save(tmp_path / "if.npy", np.asarray(scene_rec.iq))
    code, out, err = cli("import", "array", str(tmp_path / "if.npy"), "--radar-config", str(tmp_path / "paper.json"),
                         *site_args(scene_rec), "--out", str(tmp_path / "if.h5"))
    assert code == 0, err
    back = read_recording(tmp_path / "if.h5")
    assert back.domain == "if" and back.n_chirps == config["n_chirps"]
    for name in ("carrier_hz", "bandwidth_hz", "ramp_s", "pri_s", "sample_rate_hz"):
        assert getattr(back.config, name) == config[name], name
    code, doc = check_json(cli, registry_db, tmp_path / "if.h5")
    # served and decided: one unsigned dwell at the default targets is inconclusive (exit 4)
    assert code == 4 and doc["decision"] == "inconclusive" and doc["radar"] is not None, doc
    assert "radar-inconclusive" in doc["reasons"] and doc["radar"]["verification"]["llr"] is not None, doc
    code, out, err = cli("import", "array", str(tmp_path / "if.npy"), "--radar-config", str(tmp_path / "paper.json"),
                         "--domain", "cw", *site_args(scene_rec), "--out", str(tmp_path / "cw.h5"))
    assert code == 2 and "describes an IF waveform only" in err


def test_import_json_names_what_it_wrote(scene_rec, cli, tmp_path) -> None:
    import json

    np.save(tmp_path / "if.npy", np.asarray(scene_rec.iq))
    c = scene_rec.config
    code, out, err = cli("import", "array", str(tmp_path / "if.npy"), "--domain", "if", "--carrier-hz",
                         repr(c.carrier_hz), "--pri-s", repr(c.pri_s), "--bandwidth-hz", repr(c.bandwidth_hz),
                         "--ramp-s", repr(c.ramp_s), "--sample-rate-hz", repr(c.sample_rate_hz),
                         *site_args(scene_rec), "--out", str(tmp_path / "parts"), "--pulses-per-dwell", "200",
                         "--json")
    assert code == 0, err
    doc = json.loads(out)
    assert doc["domain"] == "if" and doc["shape"] == [200, 80] and len(doc["files"]) == 3
    assert all(Path(f).exists() for f in doc["files"])


def test_array_without_a_waveform_is_one_line_exit_2(scene_rec, cli, tmp_path) -> None:
    np.save(tmp_path / "if.npy", np.asarray(scene_rec.iq))
    code, _, err = cli("import", "array", str(tmp_path / "if.npy"), *site_args(scene_rec), "--out",
                       str(tmp_path / "x.h5"))
    assert code == 2 and "--domain and --carrier-hz are required (or --radar-config" in err
    assert err.count("\n") == 1 and not (tmp_path / "x.h5").exists()
