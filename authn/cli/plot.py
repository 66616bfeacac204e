"""`authn plot`: the paper's figures 2-6 of recorded returns as PNG files."""

from __future__ import annotations

from pathlib import Path

import typer



def plot(
    files: list[Path] = typer.Argument(..., help="Recorded returns (.h5/.npz); several = mean views."),
    out: Path = typer.Option(..., "--out", help="Directory for the PNG files."),
    no_clutter_suppression: bool = typer.Option(False, "--no-clutter-suppression",
                                                help="Keep the zero-Doppler (stationary) part."),
) -> None:
    """Plot the paper's figures 2-6 of one return (or the mean of several) as PNG files.

    Writes rd_map.png, spectrogram.png, mean_spectrogram.png, doppler_intensity.png
    and cadence_velocity.png (several files of the same shape are averaged). A CW file has
    no range axis: no rd_map.png (a line on stderr says so).

    Example: authn plot m300.h5 --out plots/
    """
    import numpy as np

    from signatures.errors import SignaturesError
    from signatures.recording import read_recording
    from signatures.dsp.timefreq import mean_spectrogram
    from signatures.views import views

    recs = [read_recording(f) for f in files]
    shapes = {(r.iq.shape, r.config.pri_s) for r in recs}
    if len(shapes) > 1:
        raise SignaturesError("plot: all files must share the cube shape and PRI to be averaged")
    vs = [views(r, clutter_suppression=not no_clutter_suppression) for r in recs]
    out.mkdir(parents=True, exist_ok=True)

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    def norm_db(p: np.ndarray) -> np.ndarray:
        p = np.asarray(p, dtype=np.float64)
        return 10 * np.log10(np.maximum(p / max(float(p.max()), 1e-300), 1e-12))

    def mean_of(arrays: list[np.ndarray]) -> np.ndarray:
        return np.mean([a / max(float(a.sum()), 1e-300) for a in arrays], axis=0)

    label = files[0].name if len(files) == 1 else f"mean of {len(files)} returns"
    v0 = vs[0]
    written = []

    def save(fig, name: str) -> None:
        path = out / name
        fig.savefig(path, dpi=110, bbox_inches="tight")
        plt.close(fig)
        written.append(path)

    if getattr(recs[0], "domain", "if") == "cw":  # one sample per pulse: no range axis to map
        typer.echo("rd_map.png: skipped (a CW recording has no range axis)", err=True)
    else:
        rd_power = mean_of([v.rd_map.power for v in vs])
        fig, ax = plt.subplots(figsize=(7, 5))
        m = ax.pcolormesh(v0.rd_map.range_m, v0.rd_map.velocity_mps, norm_db(rd_power), vmin=-60, vmax=0,
                          shading="auto", cmap="viridis")
        ax.set(xlabel="range (m)", ylabel="radial velocity (m/s, + receding)", title=f"Range-Doppler map: {label}")
        fig.colorbar(m, label="dB")
        save(fig, "rd_map.png")

    t_ms = v0.spectrogram.time_s * 1e3
    f_khz = v0.spectrogram.doppler_hz / 1e3
    for name, power, title in (
        ("spectrogram.png", vs[0].spectrogram.power, f"Spectrogram at the target: {files[0].name}"),
        ("mean_spectrogram.png", mean_spectrogram([v.spectrogram for v in vs]).power,
         f"Mean spectrogram: {label}"),
    ):
        fig, ax = plt.subplots(figsize=(7, 4.5))
        m = ax.pcolormesh(t_ms, f_khz, norm_db(power).T, vmin=-50, vmax=0, shading="auto", cmap="viridis")
        ax.set(xlabel="time (ms)", ylabel="Doppler (kHz)", title=title)
        fig.colorbar(m, label="dB")
        save(fig, name)

    fig, ax = plt.subplots(figsize=(7, 4))
    ax.plot(v0.rd_map.velocity_mps, norm_db(mean_of([v.doppler_profile for v in vs])), lw=0.8)
    ax.set(xlabel="radial velocity (m/s)", ylabel="dB", title=f"Doppler intensity at the target: {label}",
           ylim=(-70, 3))
    save(fig, "doppler_intensity.png")

    cvd = mean_of([v.cadence.magnitude for v in vs])
    fig, ax = plt.subplots(figsize=(7, 4.5))
    m = ax.pcolormesh(v0.cadence.cadence_hz, v0.cadence.doppler_hz / 1e3, norm_db(cvd ** 2).T, vmin=-40, vmax=0,
                      shading="auto", cmap="viridis")
    ax.set(xlabel="cadence frequency (Hz)", ylabel="Doppler (kHz)", title=f"Cadence-velocity diagram: {label}",
           xlim=(0, min(float(v0.cadence.cadence_hz[-1]), 1500.0)))
    fig.colorbar(m, label="dB")
    save(fig, "cadence_velocity.png")
    for p in written:
        typer.echo(str(p))
