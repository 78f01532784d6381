"""fogtemp.diagnose against the command line's `diagnose --json` on the same folders."""

import json
import shutil
from pathlib import Path

import pytest

import fogtemp


@pytest.fixture(scope="module")
def recorded_dir(tmp_path_factory):
    """The same experiment as `sim_dir` with another seed: nothing is left out."""
    out = tmp_path_factory.mktemp("recorded")
    fogtemp.simulate("paper", out=out, rate=10.0, seed=8, duration_s=1800.0, progress=False)
    return out


def test_diagnose_document_equals_the_command_line(sim_dir, recorded_dir, cli):
    ours = fogtemp.diagnose(sim_dir, recorded_dir, progress=False)
    done = cli("diagnose", "--simulated", sim_dir, "--recorded", recorded_dir, "--json")
    assert done.returncode == 0, done.stderr
    theirs = json.loads(done.stdout)
    ours.pop("seconds"), theirs.pop("seconds")
    assert ours == theirs
    assert "left_out" in ours


def test_diagnose_refuses_unpaired_runs(sim_dir, tmp_path):
    (tmp_path / "other.csv").write_text("time_s,temp_c,gyro_dph\n0,20,1\n1,20,1\n")
    with pytest.raises(ValueError, match="paired by file name"):
        fogtemp.diagnose(sim_dir, tmp_path, progress=False)
    with pytest.raises(FileNotFoundError):
        fogtemp.diagnose(sim_dir, tmp_path / "missing", progress=False)


def test_diagnose_warns_of_gaps_in_the_time_stamps(sim_dir, recorded_dir, tmp_path):
    # One recorded 10 Hz log loses the rows from 600 s to 659.9 s: a step of 60.1 s before
    # the row at 660 s, row 6600 of the original, now on line 6002 of the file (the header,
    # then 6000 rows before it).
    shutil.copytree(recorded_dir, tmp_path / "rec")
    log = sorted((tmp_path / "rec").glob("*.csv"))[0]
    lines = log.read_text().splitlines(keepends=True)
    kept = lines[:1] + [l for l in lines[1:] if not 600.0 <= float(l.split(",")[0]) < 660.0]
    assert len(kept) == len(lines) - 600
    log.write_text("".join(kept))
    note = (
        rf"{log.name}: 1 gap in the time stamps longer than 2 s, 60 s in all, the longest 60 s before line 6002; "
        "the short means they empty are left out"
    )
    with pytest.warns(UserWarning, match=note):
        fogtemp.diagnose(sim_dir, tmp_path / "rec", progress=False)


def test_diagnose_report_is_the_command_lines(sim_dir, recorded_dir, tmp_path, cli):
    # report.md, report.html, the figures and scenario-updated.toml (the simulation folder
    # holds its scenario.toml), byte for byte; the document names the updated scenario.
    done = cli("diagnose", "--simulated", sim_dir, "--recorded", recorded_dir, "--report", tmp_path / "cli", "--json")
    assert done.returncode == 0, done.stderr
    ours = fogtemp.diagnose(sim_dir, recorded_dir, report=tmp_path / "py", progress=False)
    theirs = json.loads(done.stdout)
    assert ours.pop("updated_scenario") == str(tmp_path / "py" / "scenario-updated.toml")
    assert theirs.pop("updated_scenario") == str(tmp_path / "cli" / "scenario-updated.toml")
    ours.pop("seconds"), theirs.pop("seconds")
    assert ours == theirs
    files = lambda d: {p.name: p.read_bytes() for p in sorted(Path(d).iterdir())}
    mine, cli_files = files(tmp_path / "py"), files(tmp_path / "cli")
    assert {"report.md", "report.html", "scenario-updated.toml"} <= set(mine)
    assert mine["scenario-updated.toml"].startswith(f"# {sim_dir / 'scenario.toml'} updated by".encode())
    assert sorted(mine) == sorted(cli_files)
    for name in cli_files:
        assert mine[name] == cli_files[name], name


def runs_file_from_manifest(folder, path):
    """A runs file with each run's position and Earth rate from a simulation's manifest."""
    manifest = json.loads((folder / "manifest.json").read_text())
    rows = [f"{r['name']},{r['group']},{r['input_rate_dph']!r}" for r in manifest["runs"]]
    path.write_text("run,position,input_rate_dph\n" + "\n".join(rows) + "\n")
    return path


def test_diagnose_of_runs_given_as_arrays_is_that_of_the_same_samples_as_logs(sim_dir, recorded_dir, tmp_path):
    # Oracle: the same samples read from the logs (read_log gives the values the logs hold,
    # time from the first row, as every reader does): every figure of the document is equal.
    runs_csv = runs_file_from_manifest(sim_dir, tmp_path / "runs.csv")

    def arrays(folder):
        return {p.stem: fogtemp.read_log(p, progress=False) for p in sorted(folder.glob("*.csv"))}

    sim_arrays, rec_arrays = arrays(sim_dir), arrays(recorded_dir)
    from_logs = fogtemp.diagnose(sim_dir, recorded_dir, runs_csv, progress=False)
    from_arrays = fogtemp.diagnose(sim_arrays, rec_arrays, runs_csv, progress=False)
    mixed = fogtemp.diagnose(sim_arrays, recorded_dir, runs_csv, progress=False)
    for doc in (from_logs, from_arrays, mixed):
        doc.pop("seconds")
    assert from_arrays == from_logs
    assert mixed == from_logs
    assert sorted(from_arrays["runs"]) == [f"{k}.csv" for k in sorted(sim_arrays)]


def test_diagnose_of_arrays_refuses_what_does_not_apply(sim_dir, recorded_dir):
    one = fogtemp.read_log(sorted(sim_dir.glob("*.csv"))[0], progress=False)
    with pytest.raises(TypeError, match="simulated is one run; give a dict of runs keyed by run name"):
        fogtemp.diagnose(one, recorded_dir, progress=False)
    with pytest.raises(ValueError, match="recorded holds no runs"):
        fogtemp.diagnose(sim_dir, {}, progress=False)
    with pytest.raises(TypeError, match="keys must be run names"):
        fogtemp.diagnose(sim_dir, {1: one}, progress=False)
    with pytest.raises(TypeError, match="column and unit options apply to recorded log files"):
        fogtemp.diagnose(sim_dir, {"pos1_-40C": one}, temp_column="T", progress=False)
    with pytest.raises(ValueError, match="paired by file name"):
        fogtemp.diagnose(sim_dir, {"pos1_-40C": one}, progress=False)
