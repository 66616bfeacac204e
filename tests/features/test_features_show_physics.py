"""`authn features show` prints the physics the decision's verification compares with the claim
(`signatures.classify.verify.PHYSICS_READS`, which is every estimate `verify` reads), and labels the
`rotor_count` feature, which verification does not read, as a classifier input only."""

from __future__ import annotations

import json

from authn.cli import main
from signatures.classify import verify as V
from signatures.features import FEATURE_NAMES, extract
from signatures.profiles import shipped_profiles
from signatures.radar import get_preset
from signatures.recording import write_recording
from signatures.sim.scene import Scene
from signatures.sim.simulate import simulate


class _Reads(dict):
    """A feature mapping that remembers every name read from it."""

    def __init__(self, *a) -> None:
        super().__init__(*a)
        self.read: set[str] = set()

    def get(self, k, d=None):
        self.read.add(k)
        return super().get(k, d)

    def __getitem__(self, k):
        self.read.add(k)
        return super().__getitem__(k)

    def __contains__(self, k):
        self.read.add(k)
        return super().__contains__(k)


def _phantom(tmp_path):
    scene = Scene(profile=shipped_profiles()["phantom4"], range_m=300.0, radial_speed_mps=2.0, snr_db=20.0)
    rec = simulate(scene, get_preset("paper"), seed=3)[0]
    return rec, write_recording(rec, tmp_path / "p4.h5")


def test_physics_reads_is_what_verification_reads(tmp_path):
    rec, _ = _phantom(tmp_path)
    res = extract(rec)
    p = shipped_profiles()
    for claimed in ("phantom4", "m300", "m600"):
        f = _Reads({**dict(zip(FEATURE_NAMES, map(float, res.as_array()))), **res.physics})
        V.verify(f, p[claimed], {"phantom4": 0.6, "m300": 0.4}, alternatives=[(p["m600"], None)])
        assert f.read and f.read <= set(V.PHYSICS_READS), f.read - set(V.PHYSICS_READS)
        assert "rotor_count" not in f.read


def test_show_prints_the_physics_first_and_labels_rotor_count(tmp_path, capsys):
    _, path = _phantom(tmp_path)
    capsys.readouterr()
    assert main(["features", "show", str(path)]) == 0
    lines = capsys.readouterr().out.splitlines()
    head = lines.index("physics the verification compares with the claim:")
    vector = lines.index("feature vector (the classifier's input):")
    physics = {ln.split()[0] for ln in lines[head + 1:vector]}
    assert {"flash_rate_hz", "rotors_seen"} <= physics <= set(V.PHYSICS_READS)
    rotor = next(ln for ln in lines[vector:] if ln.startswith("rotor_count "))
    assert "classifier input only" in rotor and "rotors_seen" in rotor
    assert main(["features", "show", str(path), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert "rotors_seen" in doc["verification_reads"] and "rotor_count" not in doc["verification_reads"]
    assert "rotor_count" in doc["classifier_only"]
