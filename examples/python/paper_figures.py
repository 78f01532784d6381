"""The paper's figures from arrays, with the fogtemp Python package and matplotlib.

Simulates the paper's experiment (built-in scenario: 8 start temperatures x 2 positions, 2 h
each), fits a model on position 1, compensates every position-2 run through the firmware's
Compensator, and draws
  1. raw vs compensated 100 s means of the gyro per start temperature (position 2), and
  2. the (T, dT/dt) mesh coloured by the modelled bias, with its triangles and nodes.

Usage: python examples/python/paper_figures.py [--rate HZ] [--method mesh] [--out DIR]
(--rate 1000 is the paper's rate: 2.7 GB of logs; the default 10 Hz takes seconds.)
"""

import argparse
import tempfile
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import matplotlib.tri as mtri  # noqa: E402
import numpy as np  # noqa: E402

import fogtemp  # noqa: E402


def means(time_s, values, tau_s=100.0):
    """Non-overlapping tau-second means (the paper's 100 s smoothing) with their centre times;
    windows under 90 % full are left out, as the library's bias stability does."""
    bins = np.floor(time_s / tau_s).astype(np.int64)
    count = np.bincount(bins)
    full = count >= 0.9 * count.max()
    centre = (np.arange(count.size) + 0.5) * tau_s
    return centre[full], np.bincount(bins, weights=values)[full] / count[full]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rate", type=float, default=10.0, help="gyro sample rate, Hz (paper: 1000)")
    parser.add_argument("--method", default="mesh", choices=fogtemp.METHODS)
    parser.add_argument("--out", default="paper-figures", help="folder for the PNG files")
    parser.add_argument("--logs", default=None, help="folder for the simulated logs (default: temporary)")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    logs = Path(args.logs or tempfile.mkdtemp(prefix="fogtemp-paper-"))

    sim = fogtemp.simulate("paper", out=logs, rate=args.rate)
    start_c = {r["name"]: r["start_temp_c"] for r in sim["runs"]}
    model = fogtemp.fit(sorted(logs.glob("pos1*.csv")), method=args.method)
    validation = fogtemp.validate(model, sorted(logs.glob("pos2*.csv")))
    print(
        f"validation bias stability (100 s): raw {validation['raw_bias_stability_dph']:.4f}, "
        f"compensated {validation['compensated_bias_stability_dph']:.4f} deg/h"
    )

    # Figure 1: raw vs compensated 100 s means per start temperature, position 2.
    fig, (ax_raw, ax_comp) = plt.subplots(1, 2, figsize=(12, 4.5), sharey=True)
    validation_logs = sorted(logs.glob("pos2*.csv"), key=lambda p: start_c[p.stem])
    colours = plt.cm.coolwarm(np.linspace(0, 1, len(validation_logs)))
    for colour, path in zip(colours, validation_logs):
        run = fogtemp.read_log(path)
        compensated, flags = model.compensate(run["time_s"], run["gyro_dph"], run["temp_c"])
        corrected = (flags & fogtemp.FLAG_BITS["WARMING_UP"]) == 0
        label = f"{start_c[path.stem]:+.0f} C"
        raw_t, raw_m = means(run["time_s"][corrected], run["gyro_dph"][corrected])
        comp_t, comp_m = means(run["time_s"][corrected], compensated[corrected])
        ax_raw.plot(raw_t / 60.0, raw_m - raw_m.mean(), color=colour, label=label)
        ax_comp.plot(comp_t / 60.0, comp_m - comp_m.mean(), color=colour, label=label)
    ax_raw.set_title(f"raw, 100 s means ({validation['raw_bias_stability_dph']:.4f} deg/h)")
    ax_comp.set_title(
        f"compensated ({args.method}), 100 s means ({validation['compensated_bias_stability_dph']:.4f} deg/h)"
    )
    for ax in (ax_raw, ax_comp):
        ax.set_xlabel("time since power-on, min")
        ax.grid(alpha=0.3)
    ax_raw.set_ylabel("gyro minus run mean, deg/h")
    ax_comp.legend(title="start temperature", fontsize=8, ncol=2)
    fig.suptitle(f"Position 2 (validation), simulated at {args.rate:g} Hz")
    fig.tight_layout()
    fig.savefig(out / "raw_vs_compensated.png", dpi=120)

    # Figure 2: the mesh in physical units, coloured by the modelled bias.
    axis = model.inspect()["axes"][0]
    fig, ax = plt.subplots(figsize=(7, 5.5))
    if axis["nodes"]:
        nodes = axis["nodes"]
        t = np.array([n["temp_c"] for n in nodes])
        r = np.array([n["rate_c_per_min"] for n in nodes])
        v = np.array([n["value_dph"] for n in nodes])
        tri = mtri.Triangulation(t, r, np.array(axis["triangles"]))
        shaded = ax.tripcolor(tri, v, shading="gouraud", cmap="viridis")
        ax.triplot(tri, color="white", linewidth=0.3, alpha=0.6)
        ax.plot(t, r, "k.", markersize=2)
        ax.set_title(f"mesh: {len(nodes)} nodes, {len(axis['triangles'])} triangles")
    else:
        p = axis["provenance"]
        grid_t, grid_r = np.meshgrid(
            np.linspace(p["temp_min_c"], p["temp_max_c"], 200),
            np.linspace(p["rate_min_c_per_min"], p["rate_max_c_per_min"], 200),
        )
        shaded = ax.pcolormesh(grid_t, grid_r, model.evaluate(grid_t, grid_r), shading="auto", cmap="viridis")
        ax.set_title(f"{'+'.join(axis['kind'])} model over the calibrated range")
    fig.colorbar(shaded, ax=ax, label="bias, deg/h")
    ax.set_xlabel("temperature, deg C")
    ax.set_ylabel("temperature rate, deg C/min")
    fig.tight_layout()
    fig.savefig(out / "mesh.png", dpi=120)
    print(f"wrote {out / 'raw_vs_compensated.png'} and {out / 'mesh.png'}")


if __name__ == "__main__":
    main()
