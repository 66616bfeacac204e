"""One picture of one decision: why the claim was accepted or rejected, as the radar saw it.

Four panels, from the recording and the decision's JSON (`Outcome.to_json`):
1. the range-Doppler map (a CW return: the Doppler intensity) with the radar's target (red x)
   and where the Remote ID says the drone is (orange o), inside its tolerance box;
2. the spectrogram at the target (time x Doppler): the blade flashes;
3. the cadence-velocity diagram with the measured blade-flash rate and the rate the
   registered model would give (the claimed band, +-10 % around it, drawn solid);
4. "Claimed vs measured", for a reader who is no radar expert: flash rate, rotors, range and
   velocity, each a row with the registered band (what the claim allows) and where the radar's
   measurement falls, with both values written out.
The title is the decision and its reasons. matplotlib is imported here only (the `plot` extra).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

#: the claimed flash-rate band drawn around the registered model's rate (a picture, not the test:
#: the verification's own likelihood decides, docs/classifiers.md)
CLAIMED_BAND = 0.10
#: the band of the rotor count in the fourth panel: half a rotor either way
ROTOR_BAND = 0.5
#: how far outside its band (in band half-widths) the fourth panel shows a measurement
SHOWN_BANDS = 4.0
SIZE_IN = (20.0, 4.6)
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
    fig, (ax_rd, ax_sp, ax_cv, ax_cm) = plt.subplots(1, 4, figsize=SIZE_IN,
                                                     gridspec_kw={"width_ratios": [1.2, 1.2, 1.2, 1.0]})
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
        ax_cv.axvspan(c * (1 - CLAIMED_BAND), c * (1 + CLAIMED_BAND), facecolor="orange", alpha=0.45, lw=0)
        for edge in (c * (1 - CLAIMED_BAND), c * (1 + CLAIMED_BAND)):
            ax_cv.axvline(edge, color="orange", lw=1.5)
        ax_cv.plot([], [], color="orange", lw=6, label=f"claimed {c:.0f} Hz (+-{CLAIMED_BAND:.0%})")
    if rate.get("measured"):
        ax_cv.axvline(float(rate["measured"]), color="red", lw=1.2, label=f"measured {float(rate['measured']):.0f} Hz")
    if not rate:
        ax_cv.text(0.5, 0.95, "no flash rate compared", transform=ax_cv.transAxes, ha="center", va="top",
                   color="white", fontsize=9)
    if ax_cv.get_legend_handles_labels()[0]:
        ax_cv.legend(loc="upper right", fontsize=8)

    _claimed_vs_measured(ax_cm, _rows(radar, kin))
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=DPI)
    plt.close(fig)
    return path


def _rows(radar: dict[str, Any], kin: dict[str, Any]) -> list[tuple[str, Any, Any, float, str]]:
    """(quantity, claimed, measured, band half-width, unit) of the fourth panel; a value the
    decision did not have is None."""
    compared = (radar.get("verification") or {}).get("compared") or {}
    rate, rotors = compared.get("flash_rate_hz") or {}, compared.get("rotors") or {}
    claimed_rate = rate.get("claimed")
    return [("flash rate", claimed_rate, rate.get("measured"), CLAIMED_BAND * float(claimed_rate or 0.0), "Hz"),
            ("rotors", rotors.get("claimed"), rotors.get("seen"), ROTOR_BAND, ""),
            ("range", kin.get("expected_range_m"), radar.get("range_m"), kin.get("range_tolerance_m") or 0.0, "m"),
            ("velocity", kin.get("expected_radial_velocity_mps"), radar.get("radial_velocity_mps"),
             kin.get("radial_velocity_tolerance_mps") or 0.0, "m/s")]


def _claimed_vs_measured(ax: Any, rows: list[tuple[str, Any, Any, float, str]]) -> None:
    """One row per quantity: the registered band (green, what the claim allows) and the radar's
    measurement (a dot: green inside the band, red outside), both values written beside it. The
    axis is the distance from the claimed value in band half-widths, so rows of different units
    share it; a measurement beyond `SHOWN_BANDS` sits at the edge."""
    ax.axvspan(-1.0, 1.0, color="palegreen", zorder=0, label="registered band")
    ax.axvline(0.0, color="green", lw=1)
    for y, (_, claimed, measured, half, unit) in enumerate(rows):
        if claimed is None or measured is None or half <= 0:
            ax.text(0.0, y, "not measured", ha="center", va="center", fontsize=8, color="grey")
            continue
        off = (float(measured) - float(claimed)) / half
        ax.plot(max(-SHOWN_BANDS, min(SHOWN_BANDS, off)), y, "o", ms=9,
                color="green" if abs(off) <= 1.0 else "red")
        u = f" {unit}" if unit else ""
        words = f"claimed {float(claimed):.3g}{u}, measured {float(measured):.3g}{u}"
        ax.text(-SHOWN_BANDS * 0.97, y + 0.3, words, fontsize=8, va="center")
    ax.set(yticks=range(len(rows)), yticklabels=[r[0] for r in rows], ylim=(len(rows) - 0.4, -0.6),
           xlim=(-SHOWN_BANDS, SHOWN_BANDS), xlabel="measured minus claimed (band half-widths)",
           title="Claimed vs measured")
    ax.legend(loc="lower right", fontsize=8)
