"""A recorded flight for tests that need one decided and audited check: an M300 at 400 m, 20 dB,
broadcasting its Remote ID, starting now (so the registry's validity window holds)."""

from __future__ import annotations

from datetime import datetime, timezone
from pathlib import Path

M300_SERIAL = "1581BDEM00000002"


def write_m300_flight(folder: Path, serial: str = M300_SERIAL) -> Path:
    """Write `folder/genuine.h5` (the same scene and simulator seed every time) and return it."""
    from authn.scenario import Broadcast, simulate_flight
    from signatures.profiles import shipped_profiles
    from signatures.radar import get_preset
    from signatures.recording import write_recording
    from signatures.sim.scene import Scene

    scene = Scene(profile=shipped_profiles()["m300"], range_m=400.0, radial_speed_mps=3.0, snr_db=20.0,
                  elevation_deg=10.0)
    rec, _ = simulate_flight(scene, get_preset("paper"), 11, Broadcast(serial=serial), azimuth_deg=60.0,
                             start_time=datetime.now(timezone.utc))
    return write_recording(rec, folder / "genuine.h5")
