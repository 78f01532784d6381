"""The bad-input matrix: every case raises the exception a Python user expects, with the
library's message, and none crashes the interpreter (each case also runs in a child
interpreter that must exit normally)."""

import re
import subprocess
import sys
import warnings

import numpy as np
import pytest

import fogtemp
from conftest import synthetic_runs, write_csv


@pytest.fixture(scope="module")
def small_model():
    return fogtemp.fit(synthetic_runs(runs=2), method="hybrid", progress=False)


def test_corrupt_and_truncated_blobs_raise_value_error(small_model):
    blob = small_model.to_bytes()
    for length in range(0, len(blob), max(1, len(blob) // 200)):
        with pytest.raises(ValueError, match="not a valid model"):
            fogtemp.Model.from_bytes(blob[:length])
    rng = np.random.default_rng(5)
    for _ in range(200):
        corrupt = bytearray(blob)
        corrupt[rng.integers(len(blob))] ^= 1 << int(rng.integers(8))
        with pytest.raises(ValueError, match="not a valid model"):
            fogtemp.Model.from_bytes(bytes(corrupt))
    with pytest.raises(ValueError, match="not a valid model"):
        fogtemp.Model.from_bytes(b"")
    with pytest.raises(TypeError, match=r"data must be bytes, bytearray or memoryview .* got int"):
        fogtemp.Model.from_bytes(12)
    with pytest.raises(TypeError, match=r"got str; to read a model file use Model.from_file\(path\)"):
        fogtemp.Model.from_bytes("FOGM")
    # bytearray and memoryview are blobs too; padding after the blob says how to slice it off.
    assert fogtemp.Model.from_bytes(bytearray(blob)).to_bytes() == blob
    assert fogtemp.Model.from_bytes(memoryview(blob)).to_bytes() == blob
    with pytest.raises(ValueError, match=rf"bytes after the blob .*; pass data\[:{len(blob)}\]$"):
        fogtemp.Model.from_bytes(blob + b"\xff" * 16)


def test_missing_files_raise_file_not_found(tmp_path):
    missing = tmp_path / "nope.csv"
    with pytest.raises(FileNotFoundError, match="cannot read model .*nope.fogm"):
        fogtemp.Model.from_file(tmp_path / "nope.fogm")
    with pytest.raises(FileNotFoundError, match="no such file or folder"):
        fogtemp.fit([missing], progress=False)
    with pytest.raises(FileNotFoundError, match="nope.csv"):
        fogtemp.read_log(missing, progress=False)
    with pytest.raises(FileNotFoundError):
        fogtemp.validate(tmp_path / "nope.fogm", [missing], progress=False)


def test_malformed_row_names_file_line_and_column_like_the_command_line(tmp_path, cli):
    log = tmp_path / "bad.csv"
    log.write_text("time_s,temp_c,gyro_dph\n0.0,20,1\n0.1,20,1\n0.2,20,abc\n")
    expected = f"{log}:4:3: column 'gyro_dph': not a number (found 'abc')"
    with pytest.raises(ValueError) as caught:
        fogtemp.read_log(log, progress=False)
    assert str(caught.value).startswith(expected)
    with pytest.raises(ValueError, match="skip_bad_rows=True"):
        fogtemp.fit([log], progress=False)
    done = cli("fit", "--out", tmp_path / "m.fogm", log)
    assert done.returncode == 1 and expected in done.stderr
    # Skipping is reported, not silent, with its share and, from 1 %, the advice the command
    # line gives (one of three rows).
    with pytest.warns(UserWarning, match=r"skipped 1 bad row of 3 rows \(33\.3 %\) \(skip_bad_rows\) \(check the input"):
        data = fogtemp.read_log(log, skip_bad_rows=True, progress=False)
    assert len(data["time_s"]) == 2


def test_logs_of_other_lab_tools_get_the_hint_that_fits(tmp_path):
    # Review32a F1, F4, F5, F6: in keyword form, as the command line gives them.
    spaced = tmp_path / "spaced.txt"
    spaced.write_text("  time_s  temp_c  gyro_dph  rh_pct\n     0.0   20.00      0.75    45.0\n     0.5              0.74    45.0\n")
    with pytest.raises(ValueError, match=r"spaced.txt:3:4: column 'rh_pct': .*a blank cell.*skip_lines=1, columns=\[\.\.\.\]"):
        fogtemp.read_log(spaced, progress=False)
    # Skipped and listed, the rows that are whole read in place (oracle: the values written).
    with pytest.warns(UserWarning, match="skipped 1 bad row of 2 rows"):
        data = fogtemp.read_log(spaced, skip_bad_rows=True, progress=False)
    assert list(data["temp_c"]) == [20.0] and list(data["gyro_dph"]) == [0.75]
    cases = [
        ("na.csv", "time_s,temp_c,gyro_dph\n0,20,1\n1,N/A,1\n", r"na.csv:3:2: .*found 'N/A'.*empty those cells"),
        ("nan.csv", "time_s,temp_c,gyro_dph\n0,20,1\n1,NaN,1\n", r"nan.csv:3:2: .*found 'NaN'.*empty those cells"),
        (
            "restart.csv",
            "time_s,temp_c,gyro_dph\n0,20,1\n1,20,1\n2,20,1\n3,20,1\ntime_s,temp_c,gyro_dph\n0,20,1\n",
            r"restart.csv:6:1: .*the header again.*split the file there",
        ),
        (
            "units.csv",
            "time_s,temp_c,gyro_dph\ns,degC,deg/h\n0,20,1\n",
            r"units.csv:2:1: .*skip both with skip_lines=N and name the columns with columns=\[\.\.\.\]",
        ),
        ("thousands.csv", "time_s,temp_c,gyro_dph\n999,20,1\n1,000.5,20,1\n", r"thousands.csv:3:1: .*without thousands separators"),
        ("lost.csv", "time_s,temp_c,gyro_dph\n0,,1\n0.5,,\n", r"lost.csv:3:3: .*a lost sample\?"),
    ]
    for name, text, expected in cases:
        log = tmp_path / name
        log.write_text(text)
        with pytest.raises(ValueError, match=expected):
            fogtemp.read_log(log, progress=False)


def test_decimal_comma_logs_read_with_decimal_mark_and_a_hint_without(tmp_path):
    points = "time_s;temp_c;gyro_dph\n0.0;20.5;-1.25e-3\n0.5;20.625;2.5\n"
    twin, log = tmp_path / "points.csv", tmp_path / "commas.csv"
    twin.write_text(points)
    log.write_text(points.replace(".", ","))
    with pytest.raises(ValueError, match="found '0,0'.*decimal_mark='comma'"):
        fogtemp.read_log(log, progress=False)
    got = fogtemp.read_log(log, decimal_mark="comma", progress=False)
    expected = fogtemp.read_log(twin, progress=False)
    for column in ("time_s", "temp_c", "gyro_dph"):
        np.testing.assert_array_equal(got[column], expected[column])
    np.testing.assert_array_equal(got["gyro_dph"], [-1.25e-3, 2.5])
    with pytest.raises(ValueError, match="a point in a log read with a decimal comma"):
        fogtemp.read_log(twin, decimal_mark="comma", progress=False)
    with pytest.raises(ValueError, match="decimal_mark: expected point or comma"):
        fogtemp.read_log(log, decimal_mark="dot", progress=False)


def test_date_time_logs_read_with_time_unit_datetime_and_a_hint_without(tmp_path):
    log = tmp_path / "dated.csv"
    log.write_text(
        "time_s,temp_c,gyro_dph\n2026-11-24T23:59:59.5+01:00,20,1\n"
        "2026-11-25 00:00:00.25+01:00,20,2\n2026-11-24T23:00:01Z,20,3\n"
    )
    with pytest.raises(ValueError, match="time_unit='datetime'"):
        fogtemp.read_log(log, progress=False)
    data = fogtemp.read_log(log, time_unit="datetime", progress=False)
    # Oracle: Python's datetime for the same three instants, from the first.
    from datetime import datetime

    instants = ["2026-11-24T23:59:59.5+01:00", "2026-11-25T00:00:00.25+01:00", "2026-11-24T23:00:01+00:00"]
    stamps = [datetime.fromisoformat(t).timestamp() for t in instants]
    np.testing.assert_allclose(data["time_s"], np.array(stamps) - stamps[0], atol=5e-7, rtol=0)
    with pytest.raises(ValueError, match="time_unit must be"):
        fogtemp.read_log(log, time_unit="iso", progress=False)
    # Date and time of day in two columns: the same instants as one date-time.
    split = tmp_path / "split.csv"
    split.write_text("Date,Time,temp_c,gyro_dph\n2026-11-24,23:59:59.5,20,1\n2026-11-25,00:00:00.25,20,2\n")
    both = fogtemp.read_log(split, time_unit="datetime", date_column="Date", time_column="Time", progress=False)
    np.testing.assert_allclose(both["time_s"], [0.0, 0.75], atol=5e-7, rtol=0)


def test_times_of_day_read_with_time_unit_time_of_day_across_midnight(tmp_path):
    log = tmp_path / "clock.csv"
    log.write_text("Time,temp_c,gyro_dph\n23:59:59.5,20,1\n0:00:00.25,20,2\n00:10,20,3\n")
    with pytest.raises(ValueError, match="time_unit='time_of_day'"):
        fogtemp.read_log(log, time_column="Time", progress=False)
    data = fogtemp.read_log(log, time_column="Time", time_unit="time_of_day", progress=False)
    # Oracle: Python's datetime for the same instants, the clock past midnight on the next day.
    from datetime import datetime

    instants = ["2026-11-24T23:59:59.5", "2026-11-25T00:00:00.25", "2026-11-25T00:10:00"]
    stamps = [datetime.fromisoformat(t).timestamp() for t in instants]
    np.testing.assert_allclose(data["time_s"], np.array(stamps) - stamps[0], atol=1e-9, rtol=0)


def test_gaps_in_the_time_stamps_are_warned_about_by_fit_and_validate(tmp_path):
    # Three 1 Hz warm-ups; the first loses rows 1000..1059, a step of 61 s before line 1002.
    logs = []
    for i, start in enumerate([0.0, 20.0, 40.0]):
        t = np.array([k for k in range(3600) if i != 0 or not 1000 <= k < 1060], dtype=float)
        temp = start + 15.0 * (1.0 - np.exp(-t / 600.0))
        path = tmp_path / f"run{i}.csv"
        write_csv(path, {"time_s": t, "temp_c": temp, "gyro_dph": 0.5 * (temp - 20.0)})
        logs.append(path)
    with pytest.warns(UserWarning, match=r"run0.csv: 1 gap in the time stamps .* the longest 61 s before line 1002"):
        model = fogtemp.fit(logs, method="poly", progress=False)
    gaps = [r["time_gaps"]["count"] for r in model.fit_report["runs"]]
    assert gaps == [1, 0, 0]
    # validate: the same gap against the model's max gap; the metric's 100 s windows start
    # at the first compensated 1 s block (10.5 s), and the gap leaves 50 blocks in the
    # window from 1010.5 s (left out; the closed form is in the command line's test).
    with pytest.warns(UserWarning, match=r"run0.csv: 1 gap .* 1 of the metric's 36 averaging windows"):
        doc = fogtemp.validate(model, logs, progress=False)
    windows = [(r["metric_windows"]["used"], r["metric_windows"]["left_out"]) for r in doc["runs"]]
    assert windows == [(35, 1), (36, 0), (36, 0)]
    assert [r["time_gaps"]["largest_s"] for r in doc["runs"]] == [61.0, 0.0, 0.0]


def test_missing_column_and_header_only(tmp_path):
    log = tmp_path / "cols.csv"
    log.write_text("time_s,temperature,gyro_dph\n0,20,1\n")
    with pytest.raises(ValueError, match="no column named 'temp_c'"):
        fogtemp.read_log(log, progress=False)
    empty = tmp_path / "empty.csv"
    empty.write_text("time_s,temp_c,gyro_dph\n")
    with pytest.raises(ValueError, match="no data rows"):
        fogtemp.fit([empty], progress=False)


def test_array_runs_with_nan_wrong_shapes_and_lengths(small_model):
    run = synthetic_runs(runs=1)[0]
    bad = dict(run, gyro_dph=run["gyro_dph"].copy())
    bad["gyro_dph"][17] = np.nan
    with pytest.raises(ValueError, match=r"runs\[0\]: sample 17: gyro_dph: NaN or infinite"):
        fogtemp.fit([bad], progress=False)
    backwards = dict(run, time_s=run["time_s"].copy())
    backwards["time_s"][40] = backwards["time_s"][39]
    with pytest.raises(ValueError, match="sample 40: time_s: time equal to the previous row"):
        fogtemp.fit([backwards], progress=False)
    with pytest.raises(ValueError, match="gyro_dph has 99 samples but time_s has"):
        fogtemp.fit([dict(run, gyro_dph=run["gyro_dph"][:99])], progress=False)
    with pytest.raises(ValueError, match="must be one-dimensional|must be 1-D"):
        fogtemp.fit([dict(run, time_s=run["time_s"].reshape(-1, 1))], progress=False)
    with pytest.raises(ValueError, match="no 'gyro_dph'"):
        fogtemp.fit([{"time_s": run["time_s"], "temp_c": run["temp_c"]}], progress=False)
    with pytest.raises(TypeError, match=r"runs\[0\]\['gyro_dph'\] must be numbers, got text"):
        fogtemp.fit([dict(run, gyro_dph=["x"] * len(run["time_s"]))], progress=False)
    with pytest.raises(TypeError, match="column and unit options apply to log files"):
        fogtemp.fit([run], gyro_unit="rps", progress=False)
    with pytest.raises(TypeError, match="unexpected keyword argument 'windw_s'"):
        fogtemp.fit([run], windw_s=100, progress=False)
    with pytest.raises(ValueError, match="method must be one of"):
        fogtemp.fit([run], method="spline", progress=False)
    with pytest.raises(ValueError, match="needs 200 blocks but the firmware's capacity is 128"):
        fogtemp.fit([run], blocks=200, progress=False)
    with pytest.raises(ValueError, match="no calibration points"):
        fogtemp.fit([dict(run, temp_c=np.full(len(run["time_s"]), np.nan))], progress=False)


def test_evaluate_and_compensate_refuse_bad_arrays(small_model):
    with pytest.raises(ValueError):
        small_model.evaluate(np.zeros(3), np.zeros(4))
    with pytest.raises(ValueError, match="float64"):
        small_model.evaluate([1.0, [2.0, 3.0]], 0.0)
    t = np.arange(10.0)
    with pytest.raises(ValueError, match="same length"):
        small_model.compensate(t, np.zeros(9), np.zeros(10))
    with pytest.raises(ValueError, match="one-dimensional"):
        small_model.compensate(t.reshape(2, 5), np.zeros((2, 5)), np.zeros((2, 5)))
    t[3] = np.nan
    with pytest.raises(ValueError, match=r"time_s\[3\] is not a finite number"):
        small_model.compensate(t, np.zeros(10), np.zeros(10))
    # NaN gyro or temperature is data, not an error: flagged exactly as firmware flags it.
    out, flags = small_model.compensate(np.arange(10.0), np.full(10, np.nan), np.full(10, np.nan))
    assert np.isnan(out).all() and (flags & fogtemp.FLAG_BITS["BAD_INPUT"]).all()
    with pytest.raises(ValueError, match="needs 100 blocks but the firmware's capacity is 64"):
        small_model.compensate(np.arange(10.0), np.zeros(10), np.zeros(10), capacity=64)
    empty_out, empty_flags = small_model.compensate([], [], [])
    assert empty_out.shape == (0,) and empty_flags.shape == (0,)


CHILD = r"""
import numpy as np, fogtemp
blob = bytes(range(256)) * 4
for n in range(len(blob)):
    try:
        fogtemp.Model.from_bytes(blob[:n])
    except ValueError:
        pass
try:
    fogtemp.fit([{"time_s": [0.0, 1.0], "temp_c": [np.nan, np.nan], "gyro_dph": [np.inf, 0.0]}], progress=False)
except ValueError:
    pass
print("survived")
"""


def test_the_interpreter_survives_garbage_in_a_child_process():
    done = subprocess.run([sys.executable, "-c", CHILD], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0 and done.stdout.strip() == "survived", done.stderr


def test_impossible_temperatures_and_unusable_settings(small_model, tmp_path):
    # A temperature no sensor reads (-999, 1e30, +-inf) is flagged BAD_INPUT and left out:
    # the output equals, sample for sample, that of the same stream without that reading
    # (review20 F2: inf was taken as no reading, unflagged, where the CLI and C flag it).
    run = synthetic_runs(runs=1)[0]
    t, g, temp = run["time_s"], run["gyro_dph"], run["temp_c"]
    bad_input = fogtemp.FLAG_BITS["BAD_INPUT"]
    k = int(np.flatnonzero(~np.isnan(temp))[400])
    without = temp.copy()
    without[k] = np.nan
    out_without, _ = small_model.compensate(t, g, without)
    for sentinel in (-999.0, 1e30, np.inf, -np.inf):
        spoiled = temp.copy()
        spoiled[k] = sentinel
        out, flags = small_model.compensate(t, g, spoiled)
        assert flags[k] & bad_input
        np.testing.assert_array_equal(out, out_without)
    # Calibration refuses the same reading as a bad row, naming the run and sample.
    spoiled_run = dict(run, temp_c=np.where(np.arange(t.size) == k, -999.0, temp))
    with pytest.raises(ValueError, match="not a temperature a sensor reads"):
        fogtemp.fit([spoiled_run, *synthetic_runs(runs=2, seed=5)], method="poly", progress=False)
    # Settings no fit can use are refused up front, naming the keyword.
    log = tmp_path / "run.csv"
    write_csv(log, run)
    with pytest.raises(ValueError, match="temp_scale must be a finite, non-zero number"):
        fogtemp.read_log(log, temp_scale=float("nan"), progress=False)
    with pytest.raises(ValueError, match="gyro_scale"):
        fogtemp.read_log(log, gyro_scale=float("inf"), progress=False)
    with pytest.raises(ValueError, match="window_s must be positive"):
        fogtemp.fit([log], method="poly", window_s=-5.0, progress=False)
    with pytest.raises(ValueError, match="p_enter"):
        fogtemp.fit([log], method="poly", p_enter=2.0, progress=False)
    with pytest.raises(ValueError, match="capacity must be at least 2"):
        small_model.compensate(t, g, temp, capacity=0)
    # allan() from arrays applies fit()'s rules: a NaN rate or a backward time is an error.
    gyro_nan = np.r_[np.ones(999), np.nan]
    with pytest.raises(ValueError, match=r"gyro_dph, sample 999"):
        fogtemp.allan({"time_s": np.arange(1000.0), "gyro_dph": gyro_nan}, progress=False)
    backward = np.arange(1000.0)
    backward[500] = 10.0
    with pytest.raises(ValueError, match=r"time_s\[500\]"):
        fogtemp.allan({"time_s": backward, "gyro_dph": np.ones(1000)}, progress=False)


def test_fit_reads_a_runs_file_like_the_command_line(tmp_path):
    # Four runs, two in each position: the Earth rate's projection (+-9.66 deg/h) added to
    # each gyro. With runs=, fit subtracts it (the oracle: the same fit on the unshifted
    # logs) and leaves the val run out; without it the offsets stay in the fit (here mostly
    # taken up as a false b(T), since each position holds other start temperatures).
    runs = synthetic_runs(runs=4, seed=11)
    plain, shifted = tmp_path / "plain", tmp_path / "shifted"
    plain.mkdir()
    shifted.mkdir()
    lines = ["run,position,input_rate_dph,role"]
    for i, run in enumerate(runs):
        rate = 9.66 if i % 2 == 0 else -9.66
        write_csv(plain / f"r{i}.csv", run)
        write_csv(shifted / f"r{i}.csv", dict(run, gyro_dph=run["gyro_dph"] + rate))
        lines.append(f"r{i},{'up' if rate > 0 else 'down'},{rate},cal")
    lines.append("r4,up,9.66,val")
    write_csv(shifted / "r4.csv", dict(runs[0], gyro_dph=runs[0]["gyro_dph"] + 9.66))
    runs_csv = tmp_path / "runs.csv"
    runs_csv.write_text("\n".join(lines) + "\n")
    with_runs = fogtemp.fit([shifted], method="poly", runs=runs_csv, progress=False)
    oracle = fogtemp.fit([plain / f"r{i}.csv" for i in range(4)], method="poly", progress=False)
    rms = lambda m: m.fit_report["axes"][0]["residual_rms_dph"]
    assert abs(rms(with_runs) - rms(oracle)) < 1e-6
    assert len(with_runs.fit_report["runs"]) == 4, "the val run is left out"
    without = fogtemp.fit([shifted / f"r{i}.csv" for i in range(4)], method="poly", progress=False)
    assert rms(without) > 5 * rms(oracle)
    with pytest.raises(TypeError, match="runs= names runs by their names"):
        fogtemp.fit(runs, method="poly", runs=runs_csv, progress=False)


def test_integer_keywords_out_of_range_raise_value_error_naming_the_keyword(small_model, tmp_path):
    # Negative (and too large) integers are refused like every other keyword value, naming the
    # keyword and its range (the command line's ranges for its flags); not an OverflowError.
    run = synthetic_runs(runs=1)[0]
    log = tmp_path / "run.csv"
    write_csv(log, run)
    t, g, c = run["time_s"][:10], run["gyro_dph"][:10], run["temp_c"][:10]
    cases = [
        (lambda: fogtemp.fit([run], blocks=-1, progress=False), "blocks must be 2 to 4096, got -1"),
        (lambda: fogtemp.fit([run], blocks=2**70, progress=False), f"blocks must be 2 to 4096, got {2**70}"),
        (lambda: fogtemp.fit([run], blocks=50, min_blocks=-1, progress=False), "min_blocks must be 2 to 50, got -1"),
        (lambda: fogtemp.fit([run], capacity=-5, progress=False), "capacity must be at least 2 and below 2**64, got -5"),
        (lambda: fogtemp.fit([run], max_nodes=-3, progress=False), "max_nodes must be at least 3 and below 2**64, got -3"),
        (lambda: fogtemp.fit([run], max_degree=-1, progress=False), "max_degree must be 0 to 255, got -1"),
        (lambda: fogtemp.fit([run], settled_every=-2, progress=False), "settled_every must be a non-negative integer below 2**64, got -2"),
        (lambda: fogtemp.read_log(log, skip_lines=-1, progress=False), "skip_lines must be a non-negative integer below 2**64, got -1"),
        (lambda: fogtemp.validate(small_model, [log], capacity=-1, progress=False), "capacity must be at least 2 and below 2**64, got -1"),
        (lambda: small_model.compensate(t, g, c, capacity=-1), "capacity must be at least 2 and below 2**64, got -1"),
        (lambda: small_model.compensate(t, g, c, axis=-1), "axis must be a non-negative integer below 2**64, got -1"),
        (lambda: small_model.evaluate(20.0, 0.1, axis=-1), "axis must be a non-negative integer below 2**64, got -1"),
        (lambda: small_model.evaluate(20.0, 0.1, threads=-1), "threads must be a non-negative integer below 2**64, got -1"),
        (lambda: fogtemp.simulate(out=tmp_path / "sim", seed=-1, progress=False), "seed must be a non-negative integer below 2**64, got -1"),
    ]
    for call, message in cases:
        with pytest.raises(ValueError) as caught:
            call()
        assert not isinstance(caught.value, OverflowError)
        assert str(caught.value) == message
    # numpy integers are integers; a float is not one (TypeError, naming the keyword).
    with pytest.raises(ValueError, match="blocks must be 2 to 4096, got -1"):
        fogtemp.fit([run], blocks=np.int64(-1), progress=False)
    with pytest.raises(TypeError, match=r"fit\(\): blocks must be an integer"):
        fogtemp.fit([run], blocks=2.5, progress=False)
    assert small_model.evaluate([20.0], [0.1], axis=np.int32(0), threads=np.uint8(1)).shape == (1,)
    assert not (tmp_path / "sim").exists()


def test_validate_warns_of_a_wrong_time_unit_and_of_unpaired_axes(poly_model, tmp_path):
    # As the command line warns: a log whose time stamps are milliseconds read as seconds (every
    # step a gap) and a model whose one axis meets two gyro columns.
    run = synthetic_runs(runs=1)[0]
    in_ms = dict(run, time_s=run["time_s"] * 1000.0)
    write_csv(tmp_path / "ms.csv", in_ms)
    with pytest.warns(UserWarning, match=r"are its times in another unit\? \(time_unit= s, ms, us, ns, min or h\)"):
        fogtemp.validate(poly_model, [tmp_path / "ms.csv"], progress=False)
    # Arrays are in seconds, and say so (review32a F7: arrays in ms got no such warning, in
    # validate or fit); days as spreadsheets count them make every step far too short.
    with pytest.warns(UserWarning, match=r"is time_s in another unit\? It is read in seconds"):
        fogtemp.validate(poly_model, [in_ms], progress=False)
    with pytest.warns(UserWarning, match=r"is time_s in another unit\? It is read in seconds"):
        with pytest.raises(ValueError, match="no calibration points"):
            fogtemp.fit([in_ms, in_ms], method="poly", progress=False)
    in_days = dict(run, time_s=run["time_s"] / 86400.0)
    with pytest.warns(UserWarning, match=r"faster than any gyro's logger: is time_s in another unit\?"):
        with pytest.raises(ValueError, match="no calibration points"):
            fogtemp.fit([in_days, in_days], method="poly", progress=False)
    two = tmp_path / "two.csv"
    with open(two, "w") as f:
        f.write("time_s,temp_c,gyro_dph,gyro2_dph\n")
        for t, c, g in zip(run["time_s"], run["temp_c"], run["gyro_dph"]):
            f.write(f"{float(t)!r},{'' if np.isnan(c) else repr(float(c))},{float(g)!r},{float(g)!r}\n")
    with pytest.warns(UserWarning, match=r"has 1 axis but the log is read with 2 gyro columns \(gyro_column=\)"):
        fogtemp.validate(poly_model, [two], gyro_column=["gyro_dph", "gyro2_dph"], progress=False)


def test_bools_too_large_integers_and_a_default_min_blocks_are_named(small_model, tmp_path):
    run = synthetic_runs(runs=1)[0]
    # True is an int to Python but not a count, an axis or a seed.
    for call in (
        lambda: fogtemp.fit([run], blocks=True, progress=False),
        lambda: small_model.evaluate(20.0, 0.1, axis=True),
        lambda: fogtemp.simulate(out=tmp_path / "s", seed=False, progress=False),
    ):
        with pytest.raises(TypeError, match="must be an integer, got a bool"):
            call()
    # Too large: the message states the upper limit too.
    with pytest.raises(ValueError, match=r"capacity must be at least 2 and below 2\*\*64, got 1180591620717411303424"):
        fogtemp.fit([run], capacity=2**70, progress=False)
    # blocks below the default min_blocks names both, as the command line does.
    with pytest.raises(ValueError, match=r"min_blocks 10 \(the default, 10, unless given\) exceeds blocks 5"):
        fogtemp.fit([run], blocks=5, progress=False)


def test_an_empty_or_taken_report_folder_is_refused_before_any_work(small_model, tmp_path, monkeypatch):
    # report="" would write into the current folder, over what is there; a file is not a folder.
    monkeypatch.chdir(tmp_path)
    (tmp_path / "report.md").write_text("mine")
    (tmp_path / "taken").write_text("x")
    run = synthetic_runs(runs=1)[0]
    log = tmp_path / "run.csv"
    write_csv(log, run)
    calls = {
        "fit": lambda r: fogtemp.fit([run], method="poly", report=r, progress=False),
        "validate": lambda r: fogtemp.validate(small_model, [log], report=r, progress=False),
        "diagnose": lambda r: fogtemp.diagnose(tmp_path / "none", tmp_path / "none", report=r, progress=False),
    }
    for name, call in calls.items():
        with pytest.raises(ValueError, match=r"report= is an empty path"):
            call("")
        with pytest.raises(ValueError, match=r"taken: exists and is not a folder"):
            call(tmp_path / "taken")
    assert (tmp_path / "report.md").read_text() == "mine"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["report.md", "run.csv", "taken"]


def test_validate_without_logs_and_a_runs_folder_are_named(small_model, tmp_path):
    with pytest.raises(ValueError, match=r"validate\(\) needs at least one log"):
        fogtemp.validate(small_model, [], progress=False)
    run = synthetic_runs(runs=1)[0]
    write_csv(tmp_path / "run.csv", run)
    with pytest.raises(ValueError, match=r"is a folder: give the runs file") as caught:
        fogtemp.validate(small_model, [tmp_path / "run.csv"], runs=tmp_path, progress=False)
    assert ":1:" not in str(caught.value)


def test_none_text_and_booleans_are_not_read_as_numbers(small_model):
    # numpy alone turns None into NaN, "20" into 20.0 and True into 1.0 without a word.
    for bad, found in ((None, "got None"), ("20", "got text"), (["20", "21"], "got text"), (True, "got booleans")):
        with pytest.raises(TypeError, match=f"temp_c must be numbers, {found}"):
            small_model.evaluate(bad, 0.1)
    with pytest.raises(TypeError, match="gyro_dph must be numbers, got text"):
        small_model.compensate(np.arange(3.0), np.array(["1", "2", "3"]), np.zeros(3))
    # None inside a list is a missing value, as pandas reads an empty cell: NaN out.
    values = small_model.evaluate([20.0, None], [0.1, 0.1])
    assert np.isfinite(values[0]) and np.isnan(values[1])
    assert values[0] == small_model.evaluate(20.0, 0.1)


def test_allan_of_a_series_too_short_warns_and_gives_no_noise_terms():
    # Three samples hold no averaging time: the noise terms are unknown (None), not zero.
    with pytest.warns(UserWarning, match=r"3 samples are too few for an Allan deviation \(at least 4\)"):
        doc = fogtemp.allan({"time_s": [0.0, 1.0, 2.0], "gyro_dph": [1.0, 2.0, 3.0]})
    axis = doc["axes"][0]
    assert axis["curve"] == [] and axis["arw_deg_per_sqrt_h"] is None and axis["bias_instability_dph"] is None


def write_gyro_logs(folder, gyro_header, gyro_cells, time_header="time_s", time_per_s=1.0):
    """Three synthetic runs as logs with columns `time_header` (seconds times `time_per_s`),
    temp_c and `gyro_header`, the gyro cells written by `gyro_cells(gyro_dph)`; returns their
    paths."""
    logs = []
    for k, run in enumerate(synthetic_runs(runs=3)):
        path = folder / f"run{k}.csv"
        with open(path, "w") as f:
            f.write(f"{time_header},temp_c,{gyro_header}\n")
            for t, c, g in zip(run["time_s"], run["temp_c"], run["gyro_dph"]):
                cell = "" if np.isnan(c) else repr(float(c))
                f.write(f"{float(t) * time_per_s!r},{cell},{gyro_cells(float(g))}\n")
        logs.append(path)
    return logs


def test_validate_reads_the_columns_the_model_records_and_refuses_swapped_ones(tmp_path):
    # Review6 F2: a model fitted on log files records each axis's gyro and temperature column;
    # validate() reads them when none are named and refuses a gyro column fitted on another axis.
    logs = write_gyro_logs(tmp_path, "gyro_x,gyro_y", lambda g: f"{g!r},{-g!r}")
    model = fogtemp.fit(logs, method="poly", gyro_column=["gyro_x", "gyro_y"], progress=False)
    axes = model.inspect()["axes"]
    assert [(a["gyro_column"], a["temp_column"]) for a in axes] == [("gyro_x", "temp_c"), ("gyro_y", "temp_c")]
    by_default = fogtemp.validate(model, logs[:1], progress=False)
    in_order = fogtemp.validate(model, logs[:1], gyro_column=["gyro_x", "gyro_y"], progress=False)
    assert [r["axis"] for r in by_default["runs"]] == [0, 1]
    assert by_default["runs"] == in_order["runs"]
    with pytest.raises(ValueError, match=r"gyro_column= gives 'gyro_y' for axis 0, but the model's axis 0 was fitted on 'gyro_x'"):
        fogtemp.validate(model, logs[:1], gyro_column=["gyro_y", "gyro_x"], progress=False)
    # Runs given as one gyro and one temperature array each are the columns gyro_dph and temp_c
    # (as fit() takes them); two gyro arrays have made-up names: none are recorded.
    single = fogtemp.fit(synthetic_runs(runs=3), method="poly", progress=False)
    assert [(a["gyro_column"], a["temp_column"]) for a in single.inspect()["axes"]] == [("gyro_dph", "temp_c")]
    two = [dict(r, gyro_dph=np.column_stack([r["gyro_dph"], -r["gyro_dph"]])) for r in synthetic_runs(runs=3)]
    from_arrays = fogtemp.fit(two, method="poly", progress=False)
    assert [a["gyro_column"] for a in from_arrays.inspect()["axes"]] == [None, None]


def test_validate_on_the_calibration_logs_warns_that_the_figures_are_in_sample(poly_model, cal_logs, val_logs):
    # As the command line: the logs' digest equals the model's input digest.
    with pytest.warns(UserWarning, match=r"these 8 logs are the ones .* was fitted on \(its input digest matches\)"):
        fogtemp.validate(poly_model, cal_logs, progress=False)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        fogtemp.validate(poly_model, val_logs[:2], progress=False)
    assert not [w for w in caught if "in-sample" in str(w.message)]


def test_validate_reads_logs_in_the_units_the_model_was_fitted_in(tmp_path):
    # The model records how fit() read the numbers: validate() reads the logs the same way when
    # no unit keyword is given, and says so.
    logs = write_gyro_logs(tmp_path, "gyro_dps", lambda g: f"{g / 3600.0!r}")
    model = fogtemp.fit(logs, method="poly", gyro_column="gyro_dps", gyro_unit="dps", progress=False)
    axis = model.inspect()["axes"][0]
    assert (axis["gyro_dph_per_unit"], axis["temp_c_per_unit"], axis["temp_offset_c"]) == (3600.0, 1.0, 0.0)
    named = fogtemp.validate(model, logs[:1], gyro_unit="dps", progress=False)
    with pytest.warns(UserWarning, match=r"the gyro is read as the model was fitted: 3600 deg/h per unit \(gyro_unit=/gyro_scale="):
        recorded = fogtemp.validate(model, logs[:1], progress=False)
    assert recorded["runs"] == named["runs"]
    # Review10 F2: read_log(model=) gives the arrays Model.compensate takes, in deg/h.
    with pytest.warns(UserWarning, match=r"the gyro is read as the model was fitted"):
        by_model = fogtemp.read_log(logs[0], model=model, progress=False)
    by_hand = fogtemp.read_log(logs[0], gyro_column="gyro_dps", gyro_unit="dps", progress=False)
    np.testing.assert_array_equal(by_model["gyro_dph"], by_hand["gyro_dph"])


def test_validate_reads_the_time_the_model_records(tmp_path):
    # A model fitted on logs whose time is in milliseconds under another name records it
    # (format 5): validate() reads it so without the time keywords, with a warning that says so,
    # and the same as with them; one gyro and one temperature array are a log's time_s in s.
    ms_logs = write_gyro_logs(tmp_path, "gyro_dph", lambda g: f"{g!r}", time_header="t_ms", time_per_s=1000.0)
    model = fogtemp.fit(ms_logs, method="poly", time_column="t_ms", time_unit="ms", progress=False)
    info = model.inspect()
    assert info["format_version"] == 6
    assert (info["log_time"]["time_column"], info["log_time"]["time_unit"]) == ("t_ms", "ms")
    named = fogtemp.validate(model, ms_logs[:1], time_column="t_ms", time_unit="ms", progress=False)
    with pytest.warns(UserWarning, match=r"the logs' time is read as .* records it: column 't_ms' in ms"):
        recorded = fogtemp.validate(model, ms_logs[:1], progress=False)
    assert recorded["runs"] == named["runs"]
    # The time column alone (another logger's name for it) is still read in the recorded ms.
    renamed = tmp_path / "renamed.csv"
    renamed.write_text(ms_logs[0].read_text().replace("t_ms,", "clock,", 1))
    with pytest.warns(fogtemp.FogtempWarning, match=r"read with the time unit ms, as .* records"):
        column_only = fogtemp.validate(model, [renamed], time_column="clock", progress=False)
    assert column_only["runs"][0]["compensated_bias_stability_dph"] == named["runs"][0]["compensated_bias_stability_dph"]
    # read_log(model=) reads the log as the fit did: the same arrays as naming every option.
    with pytest.warns(UserWarning, match=r"column 't_ms' in ms"):
        by_model = fogtemp.read_log(ms_logs[0], model=model, progress=False)
    by_hand = fogtemp.read_log(ms_logs[0], time_column="t_ms", time_unit="ms", progress=False)
    assert by_model.keys() == by_hand.keys()
    for key in by_hand:
        np.testing.assert_array_equal(by_model[key], by_hand[key])
    single = fogtemp.fit(synthetic_runs(runs=3), method="poly", progress=False)
    assert single.inspect()["format_version"] == 6
    assert (single.inspect()["log_time"]["time_column"], single.inspect()["log_time"]["time_unit"]) == ("time_s", "s")


def test_validate_reads_the_shape_the_model_records(tmp_path):
    # A model fitted on headerless captures (a banner line, fields separated by semicolons)
    # records their shape (format 7): validate() and read_log(model=) read them so without the
    # shape keywords, with a warning that says so, and the same as with them; columns="" names
    # a header row.
    logs = write_gyro_logs(tmp_path, "gyro_dph", lambda g: f"{g!r}")
    captures = []
    for log in logs:
        rows = log.read_text().splitlines()[1:]
        capture = log.with_suffix(".txt")
        capture.write_text("COM3 115200 8N1\n" + "".join(r.replace(",", ";") + "\n" for r in rows))
        captures.append(capture)
    shape = dict(skip_lines=1, columns=["time_s", "temp_c", "gyro_dph"], delimiter="semicolon")
    model = fogtemp.fit(captures, method="poly", progress=False, **shape)
    info = model.inspect()
    assert info["format_version"] == 7
    assert (info["log_shape"]["skip_lines"], info["log_shape"]["delimiter"]) == (1, "semicolon")
    assert info["log_shape"]["columns"] == ["time_s", "temp_c", "gyro_dph"]
    named = fogtemp.validate(model, captures[:1], progress=False, **shape)
    with pytest.warns(UserWarning, match=r"the logs are read as .* records of its fit's logs: 1 line skipped"):
        recorded = fogtemp.validate(model, captures[:1], progress=False)
    assert recorded["runs"] == named["runs"]
    with pytest.warns(UserWarning, match=r"no header row, columns time_s,temp_c,gyro_dph"):
        by_model = fogtemp.read_log(captures[0], model=model, progress=False)
    by_hand = fogtemp.read_log(captures[0], progress=False, **shape)
    for key in by_hand:
        np.testing.assert_array_equal(by_model[key], by_hand[key])
    # The CSV twin: a header row, named so, read as the capture (the same numbers).
    with pytest.warns(UserWarning, match=r"was fitted on logs shaped otherwise"):
        csv = fogtemp.validate(model, logs[:1], columns="", skip_lines=0, delimiter="auto", progress=False)
    assert csv["runs"][0]["compensated_bias_stability_dph"] == named["runs"][0]["compensated_bias_stability_dph"]


def test_validate_names_calibration_logs_among_the_validation_logs(tmp_path):
    # A model records each calibration log's digest (format 6): validating those logs with
    # others names them as in-sample, one by one.
    logs = write_gyro_logs(tmp_path, "gyro_dph", lambda g: f"{g!r}")
    model = fogtemp.fit(logs[:2], method="poly", progress=False)
    assert len(model.inspect()["log_reading"]["log_digests"]) == 2
    with pytest.warns(fogtemp.FogtempWarning, match=r"\(1 of the 2 logs given\) is among the 2 logs .* fitted on"):
        fogtemp.validate(model, [logs[1], logs[2]], progress=False)


def test_compensate_warns_where_the_cli_notes(tmp_path):
    # Review17 F1: Model.compensate gave the raw gyro back (times in ms passed as s) or a bias
    # continued far outside the calibration (kelvin) without a word, where fogtemp-cal
    # compensate notes both.
    runs = synthetic_runs(runs=3)
    model = fogtemp.fit(runs, method="poly", progress=False)
    run = runs[1]
    with warnings.catch_warnings(record=True) as normal:
        warnings.simplefilter("always")
        out, flags = model.compensate(run["time_s"], run["gyro_dph"], run["temp_c"])
    assert np.any(out != run["gyro_dph"].astype(np.float32))
    # A calibration run: only its start-up outside the region (partial tracker windows).
    said = [str(w.message) for w in normal]
    assert len(said) == 1 and "lie outside the model's calibrated" in said[0], said
    with pytest.warns(fogtemp.FogtempWarning) as seen:
        out, flags = model.compensate(run["time_s"] * 1000.0, run["gyro_dph"], run["temp_c"])
    said = " | ".join(str(w.message) for w in seen)
    assert np.all(flags & 1) and np.array_equal(out, run["gyro_dph"].astype(np.float32))
    assert "is time_s in another unit" in said and "never corrected a sample" in said, said
    # With how far, as validate says it (since 2026-11-30). Oracle: the run's hottest reading
    # in kelvin less the calibrated maximum, within 0.5 C (the tracker's features are means).
    head = r"lie outside the model's calibrated \(T, dT/dt\) region \(flag OUTSIDE_HULL in flags\): the model is extrapolated there: all of them at most ([\d.]+) C beyond the calibrated"
    with pytest.warns(fogtemp.FogtempWarning, match=head) as seen:
        _, flags = model.compensate(run["time_s"], run["gyro_dph"], run["temp_c"] + 273.15)
    beyond_c = float(re.search(head, str(seen[0].message)).group(1))
    hottest_c = np.nanmax(run["temp_c"]) + 273.15
    assert abs(beyond_c - (hottest_c - model.inspect()["axes"][0]["provenance"]["temp_max_c"])) < 0.5, beyond_c
    outside = int(np.count_nonzero(flags & 4))
    with pytest.warns(fogtemp.FogtempWarning, match=rf"{outside} of {flags.size} samples"):
        model.compensate(run["time_s"], run["gyro_dph"], run["temp_c"] + 273.15)


def test_complex_numbers_folders_and_dataframe_columns_are_named(tmp_path):
    # Review17 F4-F6: a complex input is refused (numpy would drop its imaginary part), read_log
    # of a folder says it is one, and a run missing a column lists the ones it has.
    model = fogtemp.fit(synthetic_runs(runs=3), method="poly", progress=False)
    with pytest.raises(TypeError, match=r"temp_c must be numbers, got complex numbers"):
        model.evaluate(np.array([20.0 + 1.0j]), [0.1])
    with pytest.raises(IsADirectoryError, match=r"a folder; read_log\(\) reads one log"):
        fogtemp.read_log(tmp_path)
    run = synthetic_runs(runs=1)[0]
    renamed = {"t": run["time_s"], "T": run["temp_c"], "w": run["gyro_dph"]}
    with pytest.raises(ValueError, match=r"no 'time_s' .*it has 't', 'T', 'w'; rename, e.g. run\['time_s'\] = run.pop\('t'\)"):
        fogtemp.fit([renamed, renamed, renamed], method="poly", progress=False)


def test_an_output_folder_is_refused_before_the_fit(small_model, tmp_path):
    """Review27a 11: `fit(out=FOLDER)` fitted, then failed to move the model into place and
    lost it; `Model.save(FOLDER)` said "Not a directory". Both are refused first, by name: a log
    that does not exist would fail the fit, so the folder's error shows the check came first."""
    with pytest.raises(OSError, match="is a folder; give the path of the file to write"):
        fogtemp.fit(str(tmp_path / "no_such_log.csv"), method="poly", out=str(tmp_path), progress=False)
    with pytest.raises(OSError, match="the folder .*missing.* does not exist"):
        fogtemp.fit(str(tmp_path / "no_such_log.csv"), method="poly", out=str(tmp_path / "missing" / "m.fogm"),
                    progress=False)
    with pytest.raises(OSError, match="is a folder"):
        small_model.save(str(tmp_path))
    small_model.save(str(tmp_path / "m.fogm"))
    assert fogtemp.Model.from_file(str(tmp_path / "m.fogm")).to_bytes() == small_model.to_bytes()


def test_a_gyro_beyond_f32_and_infinite_points_are_named(small_model):
    """Review27a 2 and 3: a gyro of 1e300 came out as inf under a warning that blamed the
    temperature; an infinite temperature gave NaN marked inside the calibrated region."""
    n = 300
    times = np.arange(n) * 1.0
    gyro = np.full(n, 9.6)
    gyro[-1] = 1e300
    with pytest.raises(ValueError, match=r"gyro_dph\[299\] is 1\.000e300, beyond the f32"):
        small_model.compensate(times, gyro, np.full(n, 20.0))
    with pytest.warns(UserWarning, match=r"1 point with an infinite temp_c \(the first temp_c\[0\] = inf\)"):
        values, outside = small_model.evaluate(np.array([np.inf, 20.0]), np.array([0.0, 0.0]), return_outside=True)
    assert np.isnan(values[0]) and np.isfinite(values[1]) and not outside[0]
    with pytest.warns(UserWarning, match=r"rate_c_per_min\[1\] = -inf"):
        small_model.evaluate(np.array([20.0, 20.0]), np.array([0.0, -np.inf]))
    assert np.isnan(small_model.evaluate(np.nan, 0.0))


def test_channels_on_separate_rows_read_as_their_merged_twin(tmp_path):
    """A temperature-only row's reading goes with the next sample (review32a F5): the arrays
    of the log with the reading merged into that sample's row, and a warning counting them."""
    separate = tmp_path / "separate.csv"
    separate.write_text("time_s,temp_c,gyro_dph\n0,,1\n0.4,20.5,\n0.5,,2\n1,,3\n1,21,\n1.5,,4\n")
    merged = tmp_path / "merged.csv"
    merged.write_text("time_s,temp_c,gyro_dph\n0,,1\n0.5,20.5,2\n1,,3\n1.5,21,4\n")
    with pytest.warns(UserWarning, match=r"separate.csv: 2 rows held a temperature and no gyro reading"):
        got = fogtemp.read_log(separate, progress=False)
    want = fogtemp.read_log(merged, progress=False)
    for key in ("time_s", "temp_c", "gyro_dph"):
        np.testing.assert_array_equal(got[key], want[key])
    assert list(got["gyro_dph"]) == [1.0, 2.0, 3.0, 4.0]


def test_a_fit_without_run_metadata_warns_that_the_sensed_rate_stays_in_the_bias(tmp_path):
    """review33b F1: fit(list_of_logs) of an up position held the Earth rate as bias without a
    word. Files without a runs file name runs=; arrays are told to subtract the rate."""
    runs = synthetic_runs(seed=5, runs=3)
    with pytest.warns(UserWarning, match=r"no run metadata: .*subtract each run's input rate from its gyro_dph"):
        model = fogtemp.fit(runs, method="poly", progress=False)
    kinds = [w["kind"] for w in model.fit_report["warnings"]]
    assert "no_run_metadata" in kinds
    paths = [tmp_path / f"run{k}.csv" for k in range(3)]
    for path, run in zip(paths, runs):
        write_csv(path, run)
    with pytest.warns(UserWarning, match=r"no run metadata: .*runs file \(runs=\)"):
        fogtemp.fit(paths, method="poly", progress=False)
    table = tmp_path / "runs.csv"
    table.write_text("run,position,input_rate_dph\n" + "".join(f"run{k},up,9.67\n" for k in range(3)))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        model = fogtemp.fit(paths, method="poly", runs=table, progress=False)
    assert not [w for w in caught if "no run metadata" in str(w.message)]
    assert "no_run_metadata" not in [w["kind"] for w in model.fit_report["warnings"]]


def test_a_gap_in_the_axes_numbering_is_refused():
    """review33b F3: gyro_dph_0 and gyro_dph_2 without gyro_dph_1 fitted one axis and dropped
    the other without a word."""
    run = dict(synthetic_runs(seed=6, runs=1)[0])
    gyro = np.asarray(run.pop("gyro_dph"))
    run["gyro_dph_0"] = gyro
    run["gyro_dph_2"] = gyro
    with pytest.raises(ValueError, match=r"'gyro_dph_2' but no 'gyro_dph_1': .*numbered from 0 without gaps"):
        fogtemp.fit([run, run, run], method="poly", progress=False)


def test_allan_of_arrays_skips_bad_samples_when_asked():
    """review33b F6: allan() refused skip_bad_rows= for arrays, which fit() and validate() take.
    The oracle: allan() of the arrays with those samples removed by hand."""
    import pandas as pd

    run = synthetic_runs(seed=8, runs=1)[0]
    t, g = np.asarray(run["time_s"]), np.asarray(run["gyro_dph"]).copy()
    bad = [100, 101, 4000]
    g[bad] = np.nan
    with pytest.raises(ValueError, match=r"sample 100: NaN is not a finite rate"):
        fogtemp.allan({"time_s": t, "gyro_dph": g}, progress=False)
    with pytest.warns(UserWarning, match=r"skipped 3 bad samples of 7500 .*the first at index 100"):
        got = fogtemp.allan({"time_s": t, "gyro_dph": g}, skip_bad_rows=True, progress=False)
    keep = np.ones(t.size, dtype=bool)
    keep[bad] = False
    want = fogtemp.allan({"time_s": t[keep], "gyro_dph": g[keep]}, progress=False)
    assert got == want
    frame = pd.DataFrame({"gyro_dph": g}, index=pd.to_datetime(t, unit="s"))
    with pytest.raises(ValueError, match=r"no 'time_s': .*reset_index\(\) makes it a column"):
        fogtemp.allan(frame, progress=False)


def test_a_runs_file_names_runs_given_as_arrays_by_their_keys(tmp_path):
    """review33b F2: runs given as arrays could not carry positions, rates or roles. A dict
    {name: run} with runs= gives the model and the choice of the same runs as log files with
    the same runs file (the oracle): val runs left out, rates taken off, positions left out."""
    runs = synthetic_runs(seed=9, runs=4)
    table = tmp_path / "runs.csv"
    table.write_text(
        "run,position,input_rate_dph,role\nrun0,a,9.67,cal\nrun1,b,-9.67,cal\nrun2,c,9.67,cal\nrun3,a,9.67,val\n"
    )
    paths = [tmp_path / f"run{k}.csv" for k in range(4)]
    for path, run in zip(paths, runs):
        write_csv(path, run)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        from_files = fogtemp.fit(paths, runs=table, progress=False)
        from_arrays = fogtemp.fit({f"run{k}": run for k, run in enumerate(runs)}, runs=table, progress=False)
    assert from_arrays.inspect()["axes"] == from_files.inspect()["axes"]
    for model in (from_arrays, from_files):
        report = model.fit_report
        assert report["axes"][0]["selection"]["grouping"] == "positions"
        assert report["run_metadata"]["positions"] == ["a", "b", "c"]
        assert report["run_metadata"]["input_rates_subtracted"] is True
        assert len(report["runs"]) == 3
    assert [c["cv_bias_stability_dph"] for c in from_arrays.fit_report["axes"][0]["selection"]["candidates"]] == [
        c["cv_bias_stability_dph"] for c in from_files.fit_report["axes"][0]["selection"]["candidates"]
    ]
    with pytest.raises(TypeError, match=r"runs= names runs by their names: give runs as arrays in a dict"):
        fogtemp.fit(runs, runs=table, progress=False)
    # validate takes the same: the val run, with its rate (the means of the bias alone), as
    # the log file with the same runs file.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        by_file = fogtemp.validate(from_files, paths, runs=table, progress=False)
        by_array = fogtemp.validate(from_files, {f"run{k}": run for k, run in enumerate(runs)}, runs=table, progress=False)
    assert [r["input_rate_dph"] for r in by_array["runs"]] == [r["input_rate_dph"] for r in by_file["runs"]] == [9.67]
    for key in ("raw_bias_stability_dph", "compensated_bias_stability_dph"):
        assert by_array[key] == by_file[key]
    assert [r["compensated_mean_dph"] for r in by_array["runs"]] == [r["compensated_mean_dph"] for r in by_file["runs"]]
    # A run the file does not list: named, with the file.
    with pytest.raises(ValueError, match=r"other"):
        fogtemp.fit({"other": runs[0], "run1": runs[1], "run2": runs[2]}, runs=table, method="poly", progress=False)


def test_notes_are_a_category_of_their_own(tmp_path):
    """review33b F5: notes (no action needed) and warnings shared one category. Reading a log
    as a model was fitted gives notes only; a note is still a FogtempWarning."""
    runs = synthetic_runs(seed=12, runs=3)
    paths = [tmp_path / f"run{k}.csv" for k in range(3)]
    for path, run in zip(paths, runs):
        write_csv(path, run)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        # A unit other than the default, which read_log(model=) says it reads as fitted.
        model = fogtemp.fit(paths, method="poly", gyro_scale=2.0, progress=False)
    assert issubclass(fogtemp.FogtempNote, fogtemp.FogtempWarning)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        fogtemp.read_log(paths[0], model=model, progress=False)
    assert caught and all(issubclass(w.category, fogtemp.FogtempNote) for w in caught), [str(w.message) for w in caught]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        warnings.filterwarnings("ignore", category=fogtemp.FogtempNote)
        fogtemp.read_log(paths[0], model=model, progress=False)
    # A warning stays a warning (not a note) under the same filter.
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        warnings.filterwarnings("ignore", category=fogtemp.FogtempNote)
        fogtemp.fit(runs, method="poly", progress=False)
    assert any("no run metadata" in str(w.message) for w in caught)


def test_runs_that_calibrate_nothing_are_named_and_no_runs_is_an_error():
    """review33b F8: a 1-sample run passed silently (it gives no calibration point), and fit({})
    was read as one run without columns."""
    runs = synthetic_runs(seed=13, runs=3)
    one = {key: np.asarray(value)[:1] for key, value in runs[0].items()}
    with pytest.warns(UserWarning, match=r"1 of 4 runs gave no calibration point and calibrate nothing: tiny \(1 row, 0 s\)"):
        model = fogtemp.fit({"a": runs[0], "b": runs[1], "c": runs[2], "tiny": one}, method="poly", progress=False)
    assert "runs_without_points" in [w["kind"] for w in model.fit_report["warnings"]]
    with pytest.raises(ValueError, match="no runs: the dict of runs is empty"):
        fogtemp.fit({}, progress=False)


def test_allan_of_arrays_reads_the_numbered_axes_read_log_returns(tmp_path):
    """review33c F8: allan(read_log(...)) of a two-gyro log refused gyro_dph_0, gyro_dph_1 and
    its hint said to rename one (dropping the other). The oracle: allan of the file."""
    run = synthetic_runs(seed=14, runs=1)[0]
    log = tmp_path / "two.csv"
    with open(log, "w") as f:
        f.write("time_s,temp_c,gx,gy\n")
        for t, g in zip(run["time_s"], run["gyro_dph"]):
            f.write(f"{float(t)!r},20.0,{float(g)!r},{float(-g)!r}\n")
    arrays = fogtemp.read_log(log, gyro_column=["gx", "gy"], progress=False)
    assert {"gyro_dph_0", "gyro_dph_1"} <= set(arrays)
    got = fogtemp.allan(arrays, progress=False)
    want = fogtemp.allan(log, gyro_column=["gx", "gy"], progress=False)
    assert len(got["axes"]) == 2
    for a, b in zip(got["axes"], want["axes"]):
        # The file is read as a stream, the arrays in memory: the same curve to rounding.
        assert [p["tau_s"] for p in a["curve"]] == [p["tau_s"] for p in b["curve"]]
        np.testing.assert_allclose([p["adev_dph"] for p in a["curve"]], [p["adev_dph"] for p in b["curve"]], rtol=1e-9)
