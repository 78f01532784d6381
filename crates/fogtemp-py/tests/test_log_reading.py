"""How logs are read, against the command line: columns= as --columns takes it (review20 F8),
validate's notes on how the logs were read (F6), and the log's own time origin (F5)."""

import datetime
import json

import numpy as np
import pandas as pd
import pytest

import fogtemp
from conftest import synthetic_runs

SHAPE_LIST = dict(skip_lines=1, delimiter="semicolon", columns=["time_s", "temp_c", "gyro_dph"])
# The command line's option names as Python's keywords (fogtemp_cal::axis_columns).
CLI_TO_PYTHON = [
    ("--gyro-unit/--gyro-scale", "gyro_unit=/gyro_scale="),
    ("--temp-scale/--temp-offset", "temp_scale=/temp_offset="),
    ("--time-column/--time-unit/--sample-rate-hz/--date-column", "time_column=/time_unit=/sample_rate_hz=/date_column="),
    ("--skip-lines/--delimiter/--comment/--columns", "skip_lines=/delimiter=/comment=/columns="),
    ("--gyro-column", "gyro_column="),
    ("--temp-column", "temp_column="),
    ("--decimal-mark", "decimal_mark="),
]


def write_captures(folder, gyro_scale=1.0):
    """The synthetic runs as serial captures: a banner line, no header, ';' between fields,
    the gyro written in units of `gyro_scale` deg/h."""
    paths = []
    for k, run in enumerate(synthetic_runs(runs=3)):
        path = folder / f"cap{k}.txt"
        with open(path, "w") as f:
            f.write("COM3 115200 8N1\n")
            for t, c, g in zip(run["time_s"], run["temp_c"], run["gyro_dph"]):
                cell = "" if np.isnan(c) else repr(float(c))
                f.write(f"{float(t)!r};{cell};{float(g) / gyro_scale!r}\n")
        paths.append(path)
    return paths


def test_columns_as_the_command_line_writes_them(tmp_path, cli):
    # Review20 F8: "a,b,c" was read as one column name; now split (and trimmed) as
    # --columns a,b,c is; lists work as before, and "" still names a header row.
    captures = write_captures(tmp_path)
    by_list = fogtemp.read_log(captures[0], progress=False, **SHAPE_LIST)
    for text in ("time_s,temp_c,gyro_dph", " time_s , temp_c,gyro_dph "):
        by_text = fogtemp.read_log(captures[0], progress=False, **dict(SHAPE_LIST, columns=text))
        for key in by_list:
            np.testing.assert_array_equal(by_text[key], by_list[key])
    model = fogtemp.fit(synthetic_runs(runs=3), method="poly", progress=False)
    model_path = tmp_path / "m.fogm"
    model.save(model_path)
    done = cli(
        "validate", "--model", model_path, captures[0], "--skip-lines", "1", "--delimiter", "semicolon",
        "--columns", "time_s,temp_c,gyro_dph", "--json",
    )
    assert done.returncode == 0, done.stderr
    expected = json.loads(done.stdout)["runs"][0]
    got = fogtemp.validate(
        model_path, [captures[0]], progress=False, skip_lines=1, delimiter="semicolon", columns="time_s,temp_c,gyro_dph"
    )["runs"][0]
    for key in ("samples", "flag_samples", "raw_bias_stability_dph", "compensated_bias_stability_dph"):
        assert got[key] == expected[key], key
    # A list item with commas is the one shape that cannot be a column name of a comma-
    # separated log: refused, naming both ways to write it.
    with pytest.raises(ValueError, match=r"the list item 'time_s,temp_c,gyro_dph' holds commas: give each name "
                       r"as its own item \(\['time_s', 'temp_c', 'gyro_dph'\]\)"):
        fogtemp.read_log(captures[0], progress=False, **dict(SHAPE_LIST, columns=["time_s,temp_c,gyro_dph"]))
    # "" and []: a log with a header row.
    csv = tmp_path / "header.csv"
    csv.write_text("time_s,temp_c,gyro_dph\n0,20,1\n1,20.5,2\n")
    for header in ("", [], " "):
        np.testing.assert_array_equal(fogtemp.read_log(csv, columns=header, progress=False)["gyro_dph"], [1.0, 2.0])
    # The docstrings say what columns= takes and name the shape model= applies.
    for function in (fogtemp.read_log, fogtemp.validate, fogtemp.fit):
        assert "comma-separated" in function.__doc__, function.__name__
    for keyword in ("skip_lines", "delimiter", "comment", "columns"):
        assert keyword in fogtemp.read_log.__doc__ and keyword in fogtemp.validate.__doc__


def test_validate_notes_say_how_the_logs_were_read_as_validate_json_does(tmp_path, cli):
    # Review20 F6: the notes on the units and the shape the model records were warnings only;
    # validate --json puts them first in its notes. Oracle: the command line's document, its
    # option names written as Python's keywords.
    gyro_scale = 0.5
    captures = write_captures(tmp_path, gyro_scale=gyro_scale)
    model_path = tmp_path / "shape.fogm"
    fogtemp.fit(captures, method="poly", progress=False, out=model_path, gyro_scale=gyro_scale, **SHAPE_LIST)
    done = cli("validate", "--model", model_path, captures[0], "--json")
    assert done.returncode == 0, done.stderr
    expected = json.loads(done.stdout)["notes"]
    for flag, keyword in CLI_TO_PYTHON:
        expected = [note.replace(flag, keyword) for note in expected]
    assert any("the gyro is read as the model was fitted: 0.5 deg/h per unit" in n for n in expected), expected
    assert any("records of its fit's logs: 1 line skipped" in n for n in expected), expected
    with pytest.warns(fogtemp.FogtempWarning):
        got = fogtemp.validate(str(model_path), [captures[0]], progress=False)
    assert got["notes"] == expected


def test_read_log_returns_the_logs_time_origin(tmp_path, cli):
    # Review20 F5: time_s counts from the first row; time_origin_s is the log's own time there,
    # so time_origin_s + time_s is what fogtemp-cal compensate writes (epoch stamps as logged).
    run = synthetic_runs(runs=3)[0]
    log = tmp_path / "epoch.csv"
    with open(log, "w") as f:
        f.write("time_s,temp_c,gyro_dph\n")
        for t, c, g in zip(run["time_s"][:600], run["temp_c"], run["gyro_dph"]):
            f.write(f"{1700007200.001 + t:.3f},{'' if np.isnan(c) else repr(float(c))},{float(g)!r}\n")
    model = fogtemp.fit(synthetic_runs(runs=3), method="poly", progress=False)
    model_path = tmp_path / "m.fogm"
    model.save(model_path)
    out = tmp_path / "out.csv"
    done = cli("compensate", "--model", model_path, log, "--out", out)
    assert done.returncode == 0, done.stderr
    written = pd.read_csv(out, dtype={"time_s": str})["time_s"]
    data = fogtemp.read_log(log, progress=False)
    assert data["time_origin_s"] == 1700007300.001  # the first row's stamp, by hand
    np.testing.assert_array_equal(data["time_origin_s"] + data["time_s"], written.astype(float).to_numpy())
    frame = fogtemp.read_log(log, progress=False, as_dataframe=True)
    assert frame.attrs["time_origin_s"] == data["time_origin_s"]
    assert list(frame.columns) == ["time_s", "temp_c", "gyro_dph"]
    # Clock times: the first row's date-time as Unix time, and its time of day.
    dated = tmp_path / "dated.csv"
    dated.write_text("time_s,temp_c,gyro_dph\n2026-11-24T23:30:00.5Z,20,1\n2026-11-24T23:30:01.5Z,20,1\n")
    unix_s = datetime.datetime(2026, 11, 24, 23, 30, 0, 500000, tzinfo=datetime.timezone.utc).timestamp()
    assert fogtemp.read_log(dated, time_unit="datetime", progress=False)["time_origin_s"] == unix_s
    clock = tmp_path / "clock.csv"
    clock.write_text("time_s,temp_c,gyro_dph\n23:30:00.5,20,1\n23:30:01.5,20,1\n")
    assert fogtemp.read_log(clock, time_unit="time_of_day", progress=False)["time_origin_s"] == 23 * 3600 + 30 * 60 + 0.5
    # Timed by the sample rate: no clock of its own.
    untimed = tmp_path / "untimed.csv"
    untimed.write_text("temp_c,gyro_dph\n20,1\n20,1\n")
    assert fogtemp.read_log(untimed, sample_rate_hz=5.0, progress=False)["time_origin_s"] == 0.0
