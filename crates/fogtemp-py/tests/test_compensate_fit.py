"""compensate and fit against the command line on the same files, fit from arrays against fit
from the same data as CSV, and the JSON documents against the command's --json output."""

import io
import json
import pickle

import numpy as np
import pandas as pd
import pytest

import fogtemp
from conftest import synthetic_runs, write_csv


def compensated_by_the_command(model, log, tmp_path, cli):
    """`fogtemp-cal compensate` of `log` with `model`: its output as a DataFrame."""
    model_path = tmp_path / "m.fogm"
    model.save(model_path)
    out = tmp_path / "comp.csv"
    done = cli("compensate", "--model", model_path, log, "--out", out)
    assert done.returncode == 0, done.stderr
    return pd.read_csv(out)


def assert_equals_the_command(compensated, flags, bias, expected):
    """The command prints the core's f32 results in their shortest form: equal as f32, bit for bit."""
    assert len(compensated) == len(expected)
    np.testing.assert_array_equal(compensated.astype(np.float32), expected["compensated_dph"].to_numpy(np.float32))
    np.testing.assert_array_equal(bias.astype(np.float32), expected["bias_dph"].to_numpy(np.float32))
    np.testing.assert_array_equal(flags, expected["flags"].to_numpy(np.uint8))


def test_compensate_equals_the_command_line(mesh_model, val_logs, tmp_path, cli):
    # The simulated log with the temperature kept on every 10th row only (a 1 Hz sensor
    # beside a 10 Hz gyro): the empty cells are "no reading" to both.
    frame = pd.read_csv(val_logs[3])
    frame.loc[frame.index % 10 != 0, "temp_c"] = np.nan
    log = tmp_path / "sparse.csv"
    frame.to_csv(log, index=False, na_rep="")
    expected = compensated_by_the_command(mesh_model, log, tmp_path, cli)
    data = fogtemp.read_log(log, progress=False)
    assert np.isnan(data["temp_c"]).mean() == pytest.approx(0.9, abs=0.01)
    compensated, flags, bias = mesh_model.compensate(
        data["time_s"], data["gyro_dph"], data["temp_c"], return_bias=True
    )
    assert_equals_the_command(compensated, flags, bias, expected)
    assert (flags & fogtemp.FLAG_BITS["WARMING_UP"]).any() and not (flags & fogtemp.FLAG_BITS["WARMING_UP"]).all()


def test_read_log_keeps_impossible_temperatures_as_compensate_does(mesh_model, val_logs, tmp_path, cli):
    # Review20 F2 (the file part): a logger's -999 and a NaN temperature cell are rows the
    # command's compensate keeps (flagged BAD_INPUT); read_log refused them, and with
    # skip_bad_rows dropped them, so Model.compensate could not give the command's output.
    frame = pd.read_csv(val_logs[3]).head(3000)
    frame["temp_c"] = frame["temp_c"].astype(object)
    frame.loc[[1200, 1201], "temp_c"] = -999.0
    frame.loc[1500, "temp_c"] = "NaN"
    log = tmp_path / "bad-temps.csv"
    frame.to_csv(log, index=False)
    expected = compensated_by_the_command(mesh_model, log, tmp_path, cli)
    with pytest.raises(ValueError, match=r"bad-temps.csv:1202:"):
        fogtemp.read_log(log, progress=False)
    data = fogtemp.read_log(log, progress=False, keep_impossible_temperatures=True)
    assert len(data["time_s"]) == len(frame) == len(expected)
    assert data["temp_c"][1200] == -999.0 and data["temp_c"][1500] == np.inf
    compensated, flags, bias = mesh_model.compensate(
        data["time_s"], data["gyro_dph"], data["temp_c"], return_bias=True
    )
    assert_equals_the_command(compensated, flags, bias, expected)
    bad = (flags & fogtemp.FLAG_BITS["BAD_INPUT"]) != 0
    assert bad[[1200, 1201, 1500]].all() and bad.sum() == 3
    with pytest.raises(TypeError, match=r"keep_impossible_temperatures must be True or False"):
        fogtemp.read_log(log, progress=False, keep_impossible_temperatures="yes")
    with pytest.raises(TypeError, match=r"unexpected keyword argument 'keep_impossible_temperatures'"):
        fogtemp.validate(mesh_model, [log], progress=False, keep_impossible_temperatures=True)


def test_evaluate_return_outside_is_the_command_lines_outside_flag(mesh_model, poly_model, tmp_path, cli):
    # Review10 F1: which evaluated points lie outside the calibrated region. Oracle: the
    # command line's evaluate, whose flags column has OUTSIDE_HULL for them.
    rng = np.random.default_rng(5)
    temp_c, rate_c_per_min = rng.uniform(-40.0, 90.0, 3000), rng.uniform(-2.0, 2.0, 3000)
    points = tmp_path / "points.csv"
    pd.DataFrame({"temp_c": temp_c, "rate_c_per_min": rate_c_per_min}).to_csv(points, index=False)
    for name, model in (("mesh", mesh_model), ("poly", poly_model)):
        values, outside = model.evaluate(temp_c, rate_c_per_min, return_outside=True)
        np.testing.assert_array_equal(values, model.evaluate(temp_c, rate_c_per_min))
        assert outside.dtype == np.bool_ and outside.shape == temp_c.shape
        path = tmp_path / f"{name}.fogm"
        model.save(path)
        done = cli("evaluate", "--model", path, "--points", points)
        assert done.returncode == 0, done.stderr
        flags = pd.read_csv(io.StringIO(done.stdout))["flags"].to_numpy(np.uint8)
        np.testing.assert_array_equal(outside, (flags & fogtemp.FLAG_BITS["OUTSIDE_HULL"]) != 0)
        assert outside.any() and not outside.all(), name
    value, outside = poly_model.evaluate(-100.0, 5.0, return_outside=True)
    assert isinstance(value, float) and outside is True
    with pytest.raises(TypeError, match=r"Model.evaluate\(\): return_outside must be True or False"):
        poly_model.evaluate(20.0, 0.0, return_outside="yes")
    with pytest.raises(TypeError, match=r"Model.compensate\(\): return_bias must be True or False"):
        poly_model.compensate([0.0, 1.0], [0.0, 0.0], [20.0, 20.0], return_bias=1)


def test_compensate_accepts_any_time_origin_and_lists(mesh_model):
    run = synthetic_runs(runs=1)[0]
    a = mesh_model.compensate(run["time_s"], run["gyro_dph"], run["temp_c"])
    b = mesh_model.compensate(list(run["time_s"] - 100.0), list(run["gyro_dph"]), list(run["temp_c"]))
    np.testing.assert_array_equal(a[0], b[0])
    np.testing.assert_array_equal(a[1], b[1])
    assert a[1].dtype == np.uint8


def test_fit_from_paths_is_the_command_lines_fit(cal_logs, tmp_path, cli):
    out = tmp_path / "cli.fogm"
    done = cli("fit", "--method", "hybrid", "--out", out, "--json", *cal_logs)
    assert done.returncode == 0, done.stderr
    ours = fogtemp.fit(cal_logs, method="hybrid", out=tmp_path / "py.fogm", progress=False)
    assert ours.to_bytes() == out.read_bytes()
    assert (tmp_path / "py.fogm").read_bytes() == out.read_bytes()
    expected = json.loads(done.stdout)
    report = ours.fit_report
    expected.pop("model"), report.pop("model")
    assert report == expected


def test_fit_from_arrays_equals_fit_from_the_same_csv(tmp_path):
    runs = synthetic_runs()
    paths = []
    for k, run in enumerate(runs):
        paths.append(tmp_path / f"run{k}.csv")
        write_csv(paths[-1], run)
    for method in ("poly", "mesh", "hybrid"):
        from_csv = fogtemp.fit(paths, method=method, progress=False)
        from_arrays = fogtemp.fit(runs, method=method, progress=False)
        from_frames = fogtemp.fit([pd.DataFrame(r) for r in runs], method=method, progress=False)
        a, c, f = from_arrays.inspect(), from_csv.inspect(), from_frames.inspect()
        # Identical model in every field; only the digests (of files vs of arrays: the input
        # digest and each run's) and the name differ. The blobs differ in those bytes and the
        # CRC only. Arrays and data frames of the same samples have the same digests.
        assert a["input_digest"] != c["input_digest"]
        assert a["log_reading"]["log_digests"] == f["log_reading"]["log_digests"] != c["log_reading"]["log_digests"]
        for doc in (a, c, f):
            doc.pop("input_digest"), doc.pop("model")
            reading = doc.pop("log_reading")
            assert (reading["decimal_mark"], len(reading["log_digests"])) == ("point", len(runs))
        assert a == c == f, method
        assert len(from_arrays.to_bytes()) == len(from_csv.to_bytes())
        grid_t, grid_r = np.meshgrid(np.linspace(-25, 40, 50), np.linspace(-1, 4, 40))
        np.testing.assert_array_equal(from_arrays.evaluate(grid_t, grid_r), from_csv.evaluate(grid_t, grid_r))


def test_inspect_and_validate_documents_equal_the_command_line(mesh_model, val_logs, tmp_path, cli):
    model_path = tmp_path / "m.fogm"
    mesh_model.save(model_path)
    loaded = fogtemp.Model.from_file(model_path)
    done = cli("inspect", model_path, "--json")
    assert done.returncode == 0, done.stderr
    assert loaded.inspect() == json.loads(done.stdout)
    done = cli("validate", "--model", model_path, "--json", *val_logs[:3])
    assert done.returncode == 0, done.stderr
    ours = fogtemp.validate(model_path, val_logs[:3], progress=False)
    assert ours == json.loads(done.stdout)
    assert ours["compensated_bias_stability_dph"] > 0 and len(ours["runs"]) == 3
    done = cli("allan", val_logs[0], "--json")
    assert done.returncode == 0, done.stderr
    assert fogtemp.allan(val_logs[0], progress=False) == json.loads(done.stdout)


def test_validate_compare_and_model_objects(mesh_model, poly_model, val_logs):
    doc = fogtemp.validate(mesh_model, val_logs[:2], compare=[poly_model], progress=False)
    assert [c["polynomial_terms"] > 0 for c in doc["comparison"]] == [False, True]


def test_validate_runs_file_keeps_the_val_runs_like_the_command_line(mesh_model, cal_logs, val_logs, tmp_path, cli):
    # Two calibration and two validation logs in one folder, the runs file giving roles: as
    # `validate --runs`, only the val runs are validated; their input rates are subtracted from
    # the runs' means (the bias left), nothing else uses them or the positions.
    folder = tmp_path / "logs"
    folder.mkdir()
    for log in (*cal_logs[:2], *val_logs[:2]):
        (folder / log.name).symlink_to(log)
    model_path = tmp_path / "m.fogm"
    mesh_model.save(model_path)
    rows = [f"{p.stem},pos1,9.66,cal" for p in cal_logs[:2]] + [f"{p.stem},pos2,-9.66,val" for p in val_logs[:2]]
    runs_csv = tmp_path / "runs.csv"
    runs_csv.write_text("run,position,input_rate_dph,role\n" + "\n".join(rows) + "\n")
    ours = fogtemp.validate(model_path, folder, runs=runs_csv, progress=False)
    done = cli("validate", "--model", model_path, "--runs", runs_csv, "--json", folder)
    assert done.returncode == 0, done.stderr
    assert ours == json.loads(done.stdout)
    # A folder's runs in reading order (by the signed temperature in the name: -25C before
    # -10C), as the command lists them; logs named one by one keep the order given.
    reading = sorted(val_logs[:2], key=lambda p: float(p.stem.split("_")[-1].rstrip("C")))
    assert [r["path"] for r in ours["runs"]] == [str(folder / p.name) for p in reading]
    without = fogtemp.validate(model_path, [folder / p.name for p in reading], progress=False)
    means = ("raw_mean_dph", "compensated_mean_dph", "input_rate_dph")
    for run, bare in zip(ours["runs"], without["runs"]):
        assert run["input_rate_dph"] == -9.66 and bare["input_rate_dph"] is None
        for key in means[:2]:
            assert run[key] == pytest.approx(bare[key] + 9.66, abs=1e-9), key

    # The model, fitted on a simulation's folder, records that it is the bias alone: without
    # run metadata one note more says the means include each run's rate (review30a F3).
    extra = [n for n in without["notes"] if n not in ours["notes"]]
    assert len(extra) == 1 and "input rate taken off its gyro" in extra[0], extra

    def without_means(doc):
        runs = [{k: v for k, v in r.items() if k not in means} for r in doc["runs"]]
        notes = [n for n in doc["notes"] if n not in extra]
        return dict(doc, runs=runs, notes=notes)

    assert without_means(ours) == without_means(without)
    # The same runs file with only the val logs given: its cal rows need no log.
    only_val = [folder / p.name for p in reading]
    assert ours == fogtemp.validate(model_path, only_val, runs=runs_csv, progress=False)
    # Without roles every log is validated; roles without a val run, or a log the file does
    # not describe, are errors (the command line's messages).
    no_roles = tmp_path / "no_roles.csv"
    no_roles.write_text("run,position,input_rate_dph\n" + "\n".join(r.rsplit(",", 1)[0] for r in rows) + "\n")
    assert len(fogtemp.validate(model_path, folder, runs=no_roles, progress=False)["runs"]) == 4
    all_cal = tmp_path / "all_cal.csv"
    all_cal.write_text(runs_csv.read_text().replace(",val", ",cal"))
    with pytest.raises(ValueError, match="no run has role 'val': nothing to validate"):
        fogtemp.validate(model_path, folder, runs=all_cal, progress=False)
    missing = tmp_path / "missing.csv"
    missing.write_text("\n".join(runs_csv.read_text().splitlines()[:-1]) + "\n")
    with pytest.raises(ValueError, match=val_logs[1].stem):
        fogtemp.validate(model_path, folder, runs=missing, progress=False)


def test_a_simulations_manifest_gives_fit_and_validate_the_run_metadata(sim_dir, cal_logs, val_logs, tmp_path):
    # DESIGN.md section 3 (review27b F1): without runs=, a fogtemp simulation's manifest.json
    # beside the logs gives each run's position and input rate, as a runs file written from it
    # does. Oracles: the runs file's model and means, and the means of the same logs read from
    # a folder without the manifest less the manifest's rate.
    manifest = json.loads((sim_dir / "manifest.json").read_text())
    rates = {r["name"]: r["input_rate_dph"] for r in manifest["runs"]}
    groups = {r["name"]: r["group"] for r in manifest["runs"]}
    with pytest.warns(fogtemp.FogtempWarning, match=r"manifest\.json \(1 position: pos1\)"):
        from_manifest = fogtemp.fit(cal_logs, method="poly", progress=False)
    runs_csv = tmp_path / "runs.csv"
    runs_csv.write_text(
        "run,position,input_rate_dph\n" + "".join(f"{p.stem},{groups[p.stem]},{rates[p.stem]!r}\n" for p in cal_logs)
    )
    assert from_manifest == fogtemp.fit(cal_logs, method="poly", runs=runs_csv, progress=False)
    used = from_manifest.fit_report["run_metadata"]
    assert used["source"].endswith("manifest.json") and used["input_rates_subtracted"]
    assert used["positions"] == ["pos1"] * len(cal_logs)
    assert used["input_rates_dph"] == [rates[p.stem] for p in cal_logs]
    bare = tmp_path / "bare"
    bare.mkdir()
    for log in (*cal_logs, *val_logs[:2]):
        (bare / log.name).symlink_to(log)
    # A runs file wins over the manifest, and the Python note names runs= (review30a F6, F10).
    zero_csv = tmp_path / "zero.csv"
    zero_csv.write_text("run,position,input_rate_dph\n" + "".join(f"{p.stem},lab,0\n" for p in cal_logs))
    overridden = fogtemp.fit(cal_logs, method="poly", runs=zero_csv, progress=False)
    assert overridden != from_manifest
    assert overridden == fogtemp.fit([bare / p.name for p in cal_logs], method="poly", runs=zero_csv, progress=False)
    with pytest.warns(fogtemp.FogtempWarning, match=r"a runs file \(runs=\) overrides it"):
        fogtemp.fit(cal_logs[:3], method="poly", progress=False)
    with pytest.warns(fogtemp.FogtempWarning, match=r"manifest\.json"):
        with_rates = fogtemp.validate(from_manifest, val_logs[:2], progress=False)
    # The model records that it is the bias alone (format 8): validated on logs without run
    # metadata, a note says the means include each run's rate (review30a F3).
    with pytest.warns(fogtemp.FogtempWarning, match=r"input rate taken off its gyro .* runs="):
        without = fogtemp.validate(from_manifest, [bare / p.name for p in val_logs[:2]], progress=False)
    for run, plain, log in zip(with_rates["runs"], without["runs"], val_logs[:2]):
        assert run["input_rate_dph"] == rates[log.stem] and plain["input_rate_dph"] is None
        assert run["raw_mean_dph"] == pytest.approx(plain["raw_mean_dph"] - rates[log.stem], abs=1e-9)
    # Runs given as arrays take no runs file: the note says to take the rate off the arrays
    # (review31a F5).
    arrays = [fogtemp.read_log(p, progress=False) for p in val_logs[:1]]
    with pytest.warns(fogtemp.FogtempWarning, match="take each run's input rate off its gyro array"):
        fogtemp.validate(from_manifest, arrays, progress=False)
    assert from_manifest.inspect()["input_rates_subtracted"] is True
    assert not any("input rate" in n for n in with_rates["notes"])
    assert any("input rate taken off its gyro" in n for n in without["notes"])
    # A model fitted without metadata records none; with the manifest's rates, validate says
    # that its compensated means are then off by its calibration runs' rate.
    plain_model = fogtemp.fit([bare / p.name for p in cal_logs], method="poly", progress=False)
    assert plain_model.inspect()["input_rates_subtracted"] is None
    with pytest.warns(fogtemp.FogtempWarning, match="does not record whether its fit took its runs. input rates off"):
        fogtemp.validate(plain_model, val_logs[:2], progress=False)


def files_of(folder):
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def test_validate_report_is_the_command_lines(mesh_model, poly_model, val_logs, tmp_path, cli):
    # The same files, byte for byte, with the table of the compared models in report.md.
    mesh_model.save(tmp_path / "mesh.fogm")
    poly_model.save(tmp_path / "poly.fogm")
    logs = val_logs[:2]
    done = cli(
        "validate", "--model", tmp_path / "mesh.fogm", "--compare", tmp_path / "poly.fogm",
        "--report", tmp_path / "cli", "--json", *logs,
    )
    assert done.returncode == 0, done.stderr
    ours = fogtemp.validate(
        tmp_path / "mesh.fogm", logs, compare=[tmp_path / "poly.fogm"], report=tmp_path / "py", progress=False
    )
    assert ours == json.loads(done.stdout)
    theirs, mine = files_of(tmp_path / "cli"), files_of(tmp_path / "py")
    assert "report.md" in mine and "report.html" in mine and any(n.endswith(".svg") for n in mine)
    assert b"## Models compared on the same logs" in mine["report.md"]
    assert sorted(mine) == sorted(theirs)
    for name in theirs:
        assert mine[name] == theirs[name], name


def test_fit_report_is_the_command_lines(cal_logs, tmp_path, cli):
    # The same files, byte for byte (the model named the same in both); a file where the
    # report folder should be is refused before the fit.
    out = tmp_path / "m.fogm"
    done = cli("fit", "--method", "poly", "--out", out, "--report", tmp_path / "cli", *cal_logs)
    assert done.returncode == 0, done.stderr
    fogtemp.fit(cal_logs, method="poly", out=out, report=tmp_path / "py", progress=False)
    theirs, mine = files_of(tmp_path / "cli"), files_of(tmp_path / "py")
    assert "fit-report.md" in mine and "fit-report.html" in mine and any(n.endswith(".svg") for n in mine)
    # The model over temperature (review26b F10), referenced from the report.
    assert "fit-temperature-axis0.svg" in mine
    assert "(fit-temperature-axis0.svg)" in mine["fit-report.md"].decode()
    assert sorted(mine) == sorted(theirs)
    for name in theirs:
        assert mine[name] == theirs[name], name
    # Without out=, the title says the model was not saved (it said "Fit of <fit>", which
    # HTML shows as "Fit of ").
    fogtemp.fit(cal_logs, method="poly", report=tmp_path / "unsaved", progress=False)
    title = (tmp_path / "unsaved" / "fit-report.md").read_text().splitlines()[0]
    assert title == "# Fit of fogtemp.fit() (not saved to a file)"
    (tmp_path / "taken").write_text("x")
    with pytest.raises(ValueError, match="exists and is not a folder"):
        fogtemp.fit(cal_logs, method="poly", report=tmp_path / "taken", progress=False)


def test_read_log_dataframe_and_columns(val_logs):
    frame = fogtemp.read_log(val_logs[0], as_dataframe=True, progress=False)
    assert list(frame.columns) == ["time_s", "temp_c", "gyro_dph"]
    arrays = fogtemp.read_log(val_logs[0], progress=False)
    np.testing.assert_array_equal(frame["gyro_dph"].to_numpy(), arrays["gyro_dph"])
    assert arrays["time_s"][0] == 0.0 and np.all(np.diff(arrays["time_s"]) > 0)


def test_models_round_trip_through_bytes_files_and_pickle(mesh_model, tmp_path):
    blob = mesh_model.to_bytes()
    assert fogtemp.Model.from_bytes(blob).to_bytes() == blob
    mesh_model.save(tmp_path / "x.fogm")
    assert fogtemp.Model.from_file(tmp_path / "x.fogm").to_bytes() == blob
    assert pickle.loads(pickle.dumps(mesh_model)).to_bytes() == blob
    assert "mesh(" in repr(mesh_model) and mesh_model.axis_count == 1


def test_models_compare_and_hash_by_their_blob_bytes(mesh_model, poly_model, tmp_path):
    # Equal blobs, whatever their source (fitted here, a file, bytes, a pickle) and whether
    # they carry a fit report; hashable consistently with ==, so models key dicts and sets.
    mesh_model.save(tmp_path / "m.fogm")
    same = [
        fogtemp.Model.from_file(tmp_path / "m.fogm"),
        fogtemp.Model.from_bytes(mesh_model.to_bytes()),
        pickle.loads(pickle.dumps(mesh_model)),
    ]
    for other in same:
        assert other == mesh_model and not other != mesh_model
        assert hash(other) == hash(mesh_model)
    assert mesh_model != poly_model and not mesh_model == poly_model
    assert mesh_model != mesh_model.to_bytes() and mesh_model != None  # noqa: E711
    assert len({mesh_model, poly_model, *same}) == 2
    assert {mesh_model: "mesh"}[same[0]] == "mesh"


def test_simulate_document(tmp_path):
    doc = fogtemp.simulate("paper", out=tmp_path, rate=1.0, seed=3, duration_s=300.0, progress=False)
    assert doc["sample_rate_hz"] == 1.0 and doc["seed"] == 3 and len(doc["runs"]) == 16
    assert (tmp_path / "manifest.json").is_file()
    # Finished: the marker of a simulation being written is gone.
    assert not (tmp_path / "SIMULATION-UNFINISHED.txt").exists()


def test_logs_of_an_unfinished_simulation_are_warned_of_in_the_documents(cal_logs, tmp_path, cli):
    # review30b F7: the warning went to a Python warning only; fit_report and validate's
    # document carry it too, as the command line's --json.
    partial = tmp_path / "partial"
    partial.mkdir()
    for log in cal_logs[:3]:
        (partial / log.name).symlink_to(log)
    (partial / "SIMULATION-UNFINISHED.txt").write_text("interrupted\n")
    with pytest.warns(fogtemp.FogtempWarning, match="SIMULATION-UNFINISHED.txt: the simulation"):
        model = fogtemp.fit(partial, method="poly", progress=False)
    kinds = [w["kind"] for w in model.fit_report["warnings"]]
    assert kinds.count("unfinished_simulation") == 1, kinds
    # Last, as in the command line's document (review31a F3).
    done = cli("fit", "--method", "poly", "--json", "--out", tmp_path / "cli.fogm", partial)
    assert done.returncode == 0, done.stderr
    # The same warnings; no_run_metadata's remedy names each interface's own option
    # (--runs FILE, runs=), so its message is compared up to the remedy.
    def comparable(warnings):
        return [
            {**w, "message": w["message"].split(" To fit the bias alone")[0]} if w["kind"] == "no_run_metadata" else w
            for w in warnings
        ]

    assert comparable(json.loads(done.stdout)["warnings"]) == comparable(model.fit_report["warnings"])
    assert "no_run_metadata" in kinds
    assert kinds[-1] == "unfinished_simulation"
    with pytest.warns(fogtemp.FogtempWarning, match="SIMULATION-UNFINISHED.txt: the simulation"):
        doc = fogtemp.validate(model, partial, progress=False)
    assert "SIMULATION-UNFINISHED.txt: the simulation" in doc["notes"][-1]


def test_simulate_refuses_a_folder_of_recordings(tmp_path):
    # review27a 10: the command line refused a folder holding a log of a run's name but no
    # manifest (a lab's recordings); Python's simulate replaced the log. Now both refuse it,
    # and take a folder an interrupted simulation left (the marker) as their own.
    lab = tmp_path / "lab"
    lab.mkdir()
    (lab / "pos1_20C.csv").write_text("recorded data\n")
    with pytest.raises(ValueError, match=r"holds pos1_20C\.csv but is not a simulation's folder"):
        fogtemp.simulate("paper", out=lab, rate=1.0, duration_s=60.0, progress=False)
    assert (lab / "pos1_20C.csv").read_text() == "recorded data\n"
    (lab / "SIMULATION-UNFINISHED.txt").write_text("left by an interrupted simulate\n")
    with pytest.raises(ValueError, match=r"not a simulation's folder"):
        fogtemp.simulate("paper", out=lab, rate=1.0, duration_s=60.0, progress=False)
    (lab / "SIMULATION-UNFINISHED.txt").write_text("interrupted\n\nRuns being written:\n  pos1_20C.csv\n")
    fogtemp.simulate("paper", out=lab, rate=1.0, duration_s=60.0, progress=False)
    assert (lab / "manifest.json").is_file() and not (lab / "SIMULATION-UNFINISHED.txt").exists()


def test_several_axes_from_two_dimensional_gyro_arrays():
    runs = synthetic_runs()
    doubled = [dict(r, gyro_dph=np.column_stack([r["gyro_dph"], 2.0 * r["gyro_dph"]])) for r in runs]
    both = fogtemp.fit(doubled, method="poly", progress=False)
    single = fogtemp.fit(runs, method="poly", progress=False)
    assert both.axis_count == 2
    t, r = np.meshgrid(np.linspace(-15, 35, 20), np.linspace(0, 3, 10))
    np.testing.assert_array_equal(both.evaluate(t, r, axis=0), single.evaluate(t, r))
    # Twice the gyro: the same terms selected (the stepwise tests are scale-free), twice the
    # coefficients, up to the f32 storage of the blob.
    np.testing.assert_allclose(both.evaluate(t, r, axis=1), 2.0 * single.evaluate(t, r), rtol=1e-5, atol=1e-4)


def test_validate_runs_given_as_arrays_is_validate_of_the_same_samples_as_files(tmp_path):
    # Oracle: the same samples written as CSV logs (repr() reads back the same float64) and
    # validated from the files; every figure must be equal, run by run.
    runs = synthetic_runs(seed=11, runs=4)
    model = fogtemp.fit(runs[:3], method="poly", progress=False)
    paths = []
    for k, run in enumerate(runs):
        paths.append(tmp_path / f"r{k}.csv")
        write_csv(paths[-1], run)
    from_files = fogtemp.validate(model, paths, progress=False)
    from_arrays = fogtemp.validate(model, runs, progress=False)
    assert [r["path"] for r in from_arrays["runs"]] == [f"runs[{k}]" for k in range(4)]
    keys = ("raw_bias_stability_dph", "compensated_bias_stability_dph", "samples", "flag_samples", "metric_windows")
    keys += ("white_noise_floor",)
    for a, f in zip(from_arrays["runs"], from_files["runs"]):
        assert {k: a[k] for k in keys} == {k: f[k] for k in keys}
    # The white-noise floor against the closed form of the runs' noise: 0.05 deg/h per sample
    # at 5 Hz gives 100 s means scattered by 0.05 / sqrt(500); from the 1 s Allan deviation of
    # about 1400 s, each run's estimate carries about 1 / sqrt(2 x 1400) = 1.9 % (6 %: over three).
    for r in from_arrays["runs"]:
        floor = r["white_noise_floor"]
        assert floor["from_tau_s"] == 1.0 and floor["averaged_s"] == pytest.approx(100.0, rel=0.01)
        assert floor["floor_dph"] == pytest.approx(0.05 / np.sqrt(500.0), rel=0.06)
    for k in ("raw_bias_stability_dph", "compensated_bias_stability_dph"):
        assert from_arrays[k] == from_files[k]
    assert from_arrays["compensated_bias_stability_dph"] < from_arrays["raw_bias_stability_dph"]
    # A DataFrame is a run too; compare= replays further models on the same arrays.
    frame = fogtemp.read_log(paths[3], as_dataframe=True, progress=False)
    both = fogtemp.validate(model, [frame], compare=[model], progress=False)
    assert both["runs"][0]["compensated_bias_stability_dph"] == from_files["runs"][3]["compensated_bias_stability_dph"]
    assert [c["compensated_bias_stability_dph"] for c in both["comparison"]] == [both["compensated_bias_stability_dph"]] * 2


def test_validate_runs_given_as_arrays_refuses_file_options_and_mixed_axes(tmp_path):
    runs = synthetic_runs(seed=11, runs=3)
    model = fogtemp.fit(runs, method="poly", progress=False)
    with pytest.raises(TypeError, match="column and unit options apply to log files"):
        fogtemp.validate(model, runs, temp_column="T", progress=False)
    (tmp_path / "runs.csv").write_text("run,position,input_rate_dph\nr0,a,0\n")
    with pytest.raises(TypeError, match="runs= names runs by their names: give runs as arrays in a dict"):
        fogtemp.validate(model, runs, runs=tmp_path / "runs.csv", progress=False)
    two_axes = dict(runs[1], gyro_dph=np.stack([runs[1]["gyro_dph"]] * 2, axis=1))
    with pytest.raises(ValueError, match=r"runs\[1\]\['gyro_dph'\] has 2 columns but runs\[0\]\['gyro_dph'\] has 1"):
        fogtemp.validate(model, [runs[0], two_axes], progress=False)
    bad = dict(runs[0], gyro_dph=runs[0]["gyro_dph"].copy())
    bad["gyro_dph"][5] = np.nan
    with pytest.raises(ValueError, match=r"runs\[0\]: sample 5: gyro_dph"):
        fogtemp.validate(model, [bad], progress=False)
    with pytest.warns(UserWarning, match=r"runs\[0\]: skipped 1 bad sample of \d+ samples \(0\.0*[1-9] %\) \(skip_bad_rows\); first ones:\n  sample 5 'gyro_dph'"):
        skipped = fogtemp.validate(model, [bad], skip_bad_rows=True, progress=False)
    assert np.isfinite(skipped["compensated_bias_stability_dph"]) and skipped["runs"][0]["skipped_rows"] == 1


def test_gaps_in_runs_given_as_arrays_are_named_by_sample():
    # A run given as arrays has samples, not lines: its gap warnings name the sample index.
    runs = synthetic_runs(seed=11, runs=3)
    gappy = dict(runs[0], time_s=runs[0]["time_s"] + np.where(np.arange(len(runs[0]["time_s"])) >= 700, 60.0, 0.0))
    with pytest.warns(UserWarning, match=r"runs\[0\]: 1 gap in the time stamps longer than .* before sample 700;"):
        model = fogtemp.fit([gappy, runs[1], runs[2]], method="poly", progress=False)
    with pytest.warns(UserWarning, match=r"runs\[0\]: 1 gap in the time stamps longer than .* before sample 700;"):
        fogtemp.validate(model, [gappy], progress=False)


def test_repr_says_a_polynomial_in_t_alone():
    # Review21 F7: a cubic-t model was shown as plain poly(4 terms).
    model = fogtemp.fit(synthetic_runs(runs=3), method="cubic-t", progress=False)
    assert "T alone" in repr(model), repr(model)
    assert "axes: [poly(" in repr(model)
