"""One picture of one decision: why the claim was accepted or rejected, as the radar saw it.

Three panels, from the recording and the decision's JSON (`Outcome.to_json`):
1. the range-Doppler map (a CW return: the Doppler intensity) with the radar's target (red x)
   and where the Remote ID says the drone is (orange o), inside its tolerance box;
2. the spectrogram at the target (time x Doppler): the blade flashes;
3. the cadence-velocity diagram with the measured blade-flash rate and the rate the
   registered model would give (the claimed band: +-10 % around it).
The title is the decision and its reasons. matplotlib is imported here only (the `plot` extra).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

#: the claimed flash-rate band drawn around the registered model's rate (a picture, not the test:
#: the verification's own likelihood decides, docs/classifiers.md)
CLAIMED_BAND = 0.10
SIZE_IN = (15.0, 4.6)
DPI = 100


def _db(p: Any) -> Any:
    import numpy as np

    p = np.asarray(p, dtype=np.float64)
    return 10 * np.log10(np.maximum(p / max(float(p.max()), 1e-300), 1e-12))


def draw(rec: Any, decision: dict[str, Any], path: Path) -> Path:
    """Write the evidence figure of `decision` (the check's JSON) for recording `rec` to `path`."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Rectangle

    from signatures.views import views

    v = views(rec)
    radar, kin = decision.get("radar") or {}, decision.get("kinematics") or {}
    fig, (ax_rd, ax_sp, ax_cv) = plt.subplots(1, 3, figsize=SIZE_IN)
    verdict = f"{decision['decision'].upper()} {decision['claim']['serial']}: {', '.join(decision['reasons'])}"
    fig.suptitle(f"{Path(decision['file']).name}: {verdict}",
                 color={"accept": "green", "inconclusive": "darkorange"}.get(decision["decision"], "firebrick"))

    if rec.domain == "cw":  # no range axis: the Doppler intensity against the declared velocity
        ax_rd.plot(v.rd_map.velocity_mps, _db(v.doppler_profile), lw=0.8)
        ax_rd.set(xlabel="radial velocity (m/s, + receding)", ylabel="dB", ylim=(-70, 3),
                  title="Doppler intensity (CW: no range)")
        if radar.get("radial_velocity_mps") is not None:
            ax_rd.axvline(radar["radial_velocity_mps"], color="red", lw=1, label="radar")
        if kin.get("expected_radial_velocity_mps") is not None:
            ax_rd.axvline(kin["expected_radial_velocity_mps"], color="orange", ls="--", lw=1, label="Remote ID")
    else:
        m = ax_rd.pcolormesh(v.rd_map.range_m, v.rd_map.velocity_mps, _db(v.rd_map.power), vmin=-60, vmax=0,
                             shading="auto", cmap="viridis")
        fig.colorbar(m, ax=ax_rd, label="dB")
        ax_rd.set(xlabel="range (m)", ylabel="radial velocity (m/s, + receding)", title="Range-Doppler map")
        if radar.get("range_m") is not None:
            ax_rd.plot(radar["range_m"], radar["radial_velocity_mps"], "x", color="red", ms=10, mew=2,
                       label=f"radar: {radar.get('model')}")
        if kin.get("expected_range_m") is not None:
            r, vel = kin["expected_range_m"], kin.get("expected_radial_velocity_mps") or 0.0
            ax_rd.plot(r, vel, "o", mfc="none", color="orange", ms=10, mew=1.5, label="Remote ID")
            dr, dv = kin.get("range_tolerance_m") or 0.0, kin.get("radial_velocity_tolerance_mps") or 0.0
            ax_rd.add_patch(Rectangle((r - dr, vel - dv), 2 * dr, 2 * dv, fill=False, ec="orange", ls="--", lw=1))
    if ax_rd.get_legend_handles_labels()[0]:
        ax_rd.legend(loc="upper right", fontsize=8)

    m = ax_sp.pcolormesh(v.spectrogram.time_s * 1e3, v.spectrogram.doppler_hz / 1e3, _db(v.spectrogram.power).T,
                         vmin=-50, vmax=0, shading="auto", cmap="viridis")
    fig.colorbar(m, ax=ax_sp, label="dB")
    ax_sp.set(xlabel="time (ms)", ylabel="Doppler (kHz)", title="Spectrogram at the target")

    m = ax_cv.pcolormesh(v.cadence.cadence_hz, v.cadence.doppler_hz / 1e3, _db(v.cadence.magnitude ** 2).T,
                         vmin=-40, vmax=0, shading="auto", cmap="viridis")
    fig.colorbar(m, ax=ax_cv, label="dB")
    rate = ((radar.get("verification") or {}).get("compared") or {}).get("flash_rate_hz") or {}
    shown = max([300.0] + [3 * float(rate[k]) for k in ("claimed", "measured") if rate.get(k)])
    ax_cv.set(xlabel="cadence frequency (Hz)", ylabel="Doppler (kHz)", title="Blade-flash rate",
              xlim=(0, min(float(v.cadence.cadence_hz[-1]), shown)))
    if rate.get("claimed"):
        c = float(rate["claimed"])
        ax_cv.axvspan(c * (1 - CLAIMED_BAND), c * (1 + CLAIMED_BAND), color="white", alpha=0.25,
                      label=f"claimed {c:.0f} Hz")
    if rate.get("measured"):
        ax_cv.axvline(float(rate["measured"]), color="red", lw=1.2, label=f"measured {float(rate['measured']):.0f} Hz")
    if not rate:
        ax_cv.text(0.5, 0.95, "no flash rate compared", transform=ax_cv.transAxes, ha="center", va="top",
                   color="white", fontsize=9)
    if ax_cv.get_legend_handles_labels()[0]:
        ax_cv.legend(loc="upper right", fontsize=8)

    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=DPI)
    plt.close(fig)
    return path
