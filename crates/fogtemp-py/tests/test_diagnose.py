"""fogtemp.diagnose against the command line's `diagnose --json` on the same folders."""

import json

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
