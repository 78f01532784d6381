"""Shared fixtures: a small simulated experiment, fitted models, and the command line.

The data come from the package's own simulator (the paper scenario at 10 Hz, 30 min per run,
fixed seed), so the tests need nothing outside the repository.
"""

import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

import fogtemp

REPO = Path(__file__).resolve().parents[3]


def cli_path():
    """The `fogtemp-cal` binary: $FOGTEMP_CAL_BIN, else one built in the target folder."""
    explicit = os.environ.get("FOGTEMP_CAL_BIN")
    if explicit:
        return explicit
    target = Path(os.environ.get("CARGO_TARGET_DIR", REPO / "target"))
    for profile in ("release", "debug"):
        candidate = target / profile / "fogtemp-cal"
        if candidate.is_file():
            return str(candidate)
    return shutil.which("fogtemp-cal")


@pytest.fixture(scope="session")
def cli():
    """Runs the command line; skips when there is no binary, unless FOGTEMP_REQUIRE_CLI=1
    (CI sets it, so a missing binary fails there instead of skipping)."""
    path = cli_path()
    if path is None:
        if os.environ.get("FOGTEMP_REQUIRE_CLI") == "1":
            pytest.fail("FOGTEMP_REQUIRE_CLI=1 but no fogtemp-cal binary (set FOGTEMP_CAL_BIN)")
        pytest.skip("no fogtemp-cal binary (cargo build -p fogtemp-cli, or set FOGTEMP_CAL_BIN)")

    def run(*args):
        done = subprocess.run([path, *map(str, args)], capture_output=True, text=True)
        return done

    return run


@pytest.fixture(scope="session")
def sim_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("sim")
    fogtemp.simulate("paper", out=out, rate=10.0, seed=7, duration_s=1800.0, progress=False)
    return out


@pytest.fixture(scope="session")
def cal_logs(sim_dir):
    logs = sorted(sim_dir.glob("pos1*.csv"))
    assert len(logs) == 8, logs
    return logs


@pytest.fixture(scope="session")
def val_logs(sim_dir):
    logs = sorted(sim_dir.glob("pos2*.csv"))
    assert len(logs) == 8, logs
    return logs


@pytest.fixture(scope="session")
def mesh_model(cal_logs):
    return fogtemp.fit(cal_logs, method="mesh", progress=False)


@pytest.fixture(scope="session")
def poly_model(cal_logs):
    return fogtemp.fit(cal_logs, method="poly", progress=False)


def synthetic_runs(seed=3, runs=3, rate_hz=5.0, duration_s=1500.0):
    """Runs as arrays: warming from several start temperatures, bias in T and dT/dt plus
    white noise, a temperature reading on every fifth sample only (NaN between)."""
    rng = np.random.default_rng(seed)
    out = []
    for k in range(runs):
        t = 100.0 + np.arange(int(duration_s * rate_hz)) / rate_hz
        start_c = -20.0 + 25.0 * k
        temp = start_c + 30.0 * (1.0 - np.exp(-(t - t[0]) / 500.0))
        rate = np.gradient(temp, t) * 60.0
        gyro = 0.3 * (temp - 20.0) + 0.002 * (temp - 20.0) ** 2 + 4.0 * rate + rng.normal(0.0, 0.05, t.size)
        temp_read = np.where(np.arange(t.size) % 5 == 0, temp, np.nan)
        out.append({"time_s": t, "temp_c": temp_read, "gyro_dph": gyro})
    return out


def write_csv(path, run):
    """A run as a CSV log: repr() is the shortest text that reads back the same float64, and
    an empty cell where the temperature is NaN."""
    with open(path, "w") as f:
        f.write("time_s,temp_c,gyro_dph\n")
        for t, c, g in zip(run["time_s"], run["temp_c"], run["gyro_dph"]):
            f.write(f"{float(t)!r},{'' if np.isnan(c) else repr(float(c))},{float(g)!r}\n")
