"""The claim's own target (authn/association.py) in dwells holding several targets.

Two-target scenes are built by superposition: simulated recordings with the same radar
configuration, range window and start time are summed IQ cube to IQ cube (the radar is linear,
so the sum is physically the dwell of both targets; each adds its own receiver noise, so the
noise floor is 3 dB higher), and the file carries the Remote ID of the one whose claim is
checked. The genuine drone is an M300 registered under the serial both claim; the impostor is a
Phantom 4 that broadcasts that serial with its own (true) position. Real Checker, real Cedar.

A single check is a track of one dwell, decided by Wald's sequential test, its LLR the least over
the background and every other model registered at the site. The site here registers the M300
alone (no radar-confusable M600 beside it), so each claim is weighed against the background only,
and the checker runs at the looser targets (false accept and false reject 0.02: +-3.89 nats), where
one dwell can refute a claim. The genuine M300 beside the Phantom 4 gives a weak LLR (the Phantom
4's flashes leak into its gate): the radar favours its claim but does not accept it on one dwell
(`inconclusive`, which a valid DRIP signature would turn into an accept); what these tests show is
that each claim is verified against its own target: the genuine one is favoured, never refuted, the
impostor's is refuted.
"""

from __future__ import annotations

from dataclasses import replace
from datetime import datetime, timezone

import pytest

from authn.check import Checker
from authn.cli import main
from authn.scenario import Broadcast, simulate_flight
from authn.track import Sprt
from signatures.profiles import shipped_profiles
from signatures.radar import get_preset
from signatures.sim.scene import BirdParams, Scene

M300 = "1581BDEM00000002"
WINDOW_M = 360.0  # every recording of a scene shares this range window (paper: 360-440 m)
START = datetime.now(timezone.utc).replace(microsecond=0)


def _fly(kind: str, range_m: float, speed: float, azimuth: float, seed: int, model: str | None = None,
         serial: str | None = M300, offset: float = 0.0, snr_db: float = 20.0):
    sc = Scene(kind=kind, profile=shipped_profiles()[model] if model else None,
               bird=BirdParams() if kind == "bird" else None, snr_db=snr_db, range_m=range_m,
               radial_speed_mps=speed, elevation_deg=10.0)
    bc = Broadcast(serial=serial, offset_along_los_m=offset) if serial else None
    rec, _ = simulate_flight(sc, get_preset("paper"), seed, bc, azimuth_deg=azimuth, range_offset_m=WINDOW_M,
                             start_time=START)
    return rec


def _scene(claimant, *others):
    """The dwell of all the targets, carrying the claimant's Remote ID."""
    for o in others:
        assert o.config == claimant.config and o.start_time == claimant.start_time and o.iq.shape == claimant.iq.shape
    iq = claimant.iq.copy()
    for o in others:
        iq += o.iq
    return replace(claimant, iq=iq, simulation=None)


@pytest.fixture(scope="module")
def checker(tmp_path_factory) -> Checker:
    db = f"sqlite:///{tmp_path_factory.mktemp('target') / 'r.sqlite3'}"
    assert main(["--db", db, "register", "--serial", M300, "--model", "m300", "--valid-from", "2025-01-01"]) == 0
    return Checker(db, sprt=Sprt(0.02, 0.02))


def _check(checker: Checker, rec) -> dict:
    return checker.evaluate_recording(rec).to_json()


GENUINE = dict(kind="uav", model="m300", range_m=400.0, speed=3.0, azimuth=60.0, seed=1)


def _favoured(out: dict) -> None:
    """The genuine claim on its own target: not refuted, the radar's evidence for it (LLR > 0), so
    a valid DRIP signature would accept it; one dwell this weak is not an accept unsigned."""
    assert out["decision"] == "inconclusive" and out["reasons"] == ["radar-inconclusive"], out
    assert out["radar"]["verification"]["llr"] > 0 and out["to_decide"]["llr_nats"] > 0
    assert out["to_decide"]["signature"] is True


def _refuted(out: dict) -> None:
    """The impostor's claim on its own target: refuted on one dwell, far past the bound."""
    assert out["decision"] == "reject" and out["reasons"] == ["radar-claim-inconsistent"], out
    assert out["radar"]["verification"]["llr"] < -3.89 - 3.0


@pytest.mark.parametrize("impostor_at,impostor_speed,selected_by", [
    (420.0, -2.0, "position"),  # resolved in range, outside each other's range tolerance
    (407.0, -4.0, "velocity"),  # both within the claim's range tolerance (~8.9 m): the velocity picks
])
def test_an_impostor_beside_the_genuine_drone_cannot_borrow_its_rotors(checker, impostor_at, impostor_speed,
                                                                      selected_by) -> None:
    """A Phantom 4 next to the genuine M300 claims the M300's serial broadcasting its own position:
    the check verifies the Phantom 4's return and rejects; the M300's claim (its own position) is
    verified against the M300's return, which favours it (inconclusive on one dwell, never
    refuted), in the same dwell."""
    genuine = _fly(**GENUINE)
    impostor = _fly("uav", impostor_at, impostor_speed, 100.0, 2, "phantom4")
    ok = _check(checker, _scene(genuine, impostor))
    bad = _check(checker, _scene(impostor, genuine))
    _favoured(ok)
    _refuted(bad)
    for out, at, speed in ((ok, 400.0, 3.0), (bad, impostor_at, impostor_speed)):
        radar = out["radar"]  # the evidence is the claimant's own target: its range and velocity
        assert abs(radar["range_m"] - at) <= 1.0 and abs(radar["radial_velocity_mps"] - speed) <= 0.3, radar
        assert radar["target"] == {"selected_by": selected_by, "in_view": 2, "candidates": 1 if selected_by ==
                                   "position" else 2}
    # the impostor's own rotors contradict the claim. (The genuine drone's physics term is there too,
    # but weaker beside the Phantom 4 at 420 m, whose tip flashes the range-Doppler coupling of FMCW
    # moves into the M300's gate: rotors seen 3.3 alone, 7.6 beside it; docs/policies.md.)
    assert "physics" in ok["radar"]["verification"]["terms"] and bad["radar"]["verification"]["terms"]["physics"] < 0


def test_a_bird_and_an_impostor_in_the_dwell(checker) -> None:
    """Three targets: the genuine M300, a Phantom 4 claiming it, a bird. Each claim is its own."""
    genuine, bird = _fly(**GENUINE), _fly("bird", 380.0, 5.0, 30.0, 3, serial=None)
    impostor = _fly("uav", 420.0, -2.0, 100.0, 2, "phantom4")
    ok = _check(checker, _scene(genuine, impostor, bird))
    bad = _check(checker, _scene(impostor, genuine, bird))
    _favoured(ok)
    _refuted(bad)
    assert ok["radar"]["target"]["in_view"] == 3 and abs(ok["radar"]["range_m"] - 400.0) <= 1.0, ok
    assert bad["radar"]["target"]["in_view"] == 3 and abs(bad["radar"]["range_m"] - 420.0) <= 1.0, bad


def test_a_claim_where_no_target_is_is_no_radar_target(checker) -> None:
    """The Remote ID puts the drone 25 m beyond where the radar sees it (inside the window, outside
    the range tolerance): the targets in view (the drone, a bird) are not the claim's, so nothing is
    verified and the reason is `no-radar-target`, not `no-target`."""
    spoofed, bird = _fly(**GENUINE, offset=25.0), _fly("bird", 380.0, 5.0, 30.0, 3, serial=None)
    for rec, in_view in ((spoofed, 1), (_scene(spoofed, bird), 2)):
        out = _check(checker, rec)
        assert out["decision"] == "reject" and out["reasons"] == ["no-radar-target"], out
        assert out["radar"]["model"] == "none" and "verification" not in out["radar"]
        assert out["radar"]["target"] == {"selected_by": "declared-range", "in_view": in_view, "candidates": 0}


def test_an_empty_dwell_is_no_target(checker) -> None:
    """Nothing in the window at all (receiver noise only) against a claim inside it: `no-target`."""
    empty = _fly("none", 400.0, 0.0, 60.0, 4, serial=None)
    carrier = _fly(**GENUINE)  # its Remote ID (a claim at 400 m) on the empty dwell's cube
    out = _check(checker, replace(carrier, iq=empty.iq))
    assert out["decision"] == "reject" and out["reasons"] == ["no-target"], out
    assert out["radar"]["target"]["in_view"] == 0


def _scenes() -> list:
    """Dwells of every association rule: position (two targets resolved in range), velocity (two
    within the range tolerance), declared-range (nothing where the claim is), an empty dwell."""
    genuine = _fly(**GENUINE)
    near, far = _fly("uav", 407.0, -4.0, 100.0, 2, "phantom4"), _fly("uav", 420.0, -2.0, 100.0, 2, "phantom4")
    bird = _fly("bird", 380.0, 5.0, 30.0, 3, serial=None)
    empty = _fly("none", 400.0, 0.0, 60.0, 4, serial=None)
    return [_scene(genuine, far), _scene(near, genuine), _scene(far, genuine, bird), _scene(genuine, near),
            _scene(_fly(**GENUINE, offset=25.0), bird), replace(genuine, iq=empty.iq)]


def _decided(out: dict) -> dict:
    return {k: v for k, v in out.items() if k not in ("timings_ms", "audit_id", "dwell_start")}


def test_a_batch_associates_each_claim_as_a_single_check_does(checker) -> None:
    """Checked together (one feature batch on scipy's float32 transforms, the targets taken from
    that batch's own range profiles, a velocity pick extracting features inside it), every dwell
    is decided exactly as when it is checked alone: same decision, reasons, target and evidence."""
    from authn.check import CheckInput

    scenes = _scenes()
    alone = [_decided(_check(checker, rec)) for rec in scenes]
    together = checker.decide([CheckInput.recording(rec) for rec in scenes])
    assert [_decided(o.to_json()) for o in together.items] == alone
    assert [o["radar"]["target"]["selected_by"] for o in alone] == ["position", "velocity", "position", "velocity",
                                                                      "declared-range", "declared-range"]


@pytest.mark.parametrize("batch", [1, 3])
def test_one_range_transform_per_return_associated_by_position(checker, monkeypatch, batch) -> None:
    """The association takes its targets from the feature stage's range profile: each return's
    cube is range-transformed once (not once more to list its targets)."""
    from authn.check import CheckInput
    from signatures.dsp import extraction

    rows: list[int] = []
    real = extraction._range_spectra

    def counted(a, *args, **kwargs):
        rows.append(a.shape[0])
        return real(a, *args, **kwargs)

    monkeypatch.setattr(extraction, "_range_spectra", counted)
    scenes = [_scene(_fly(**GENUINE), _fly("uav", 420.0, -2.0, 100.0, 2, "phantom4"))] * batch
    out = checker.decide([CheckInput.recording(rec) for rec in scenes])
    assert [o.to_json()["radar"]["target"]["selected_by"] for o in out.items] == ["position"] * batch
    assert sum(rows) == batch
