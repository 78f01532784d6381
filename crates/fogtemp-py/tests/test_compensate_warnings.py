"""Model.compensate's warnings where fogtemp-cal compensate notes or refuses the same input
(review20 F3: time that goes back; F7: temperature glitches)."""

import re
import warnings

import numpy as np
import pytest

import fogtemp
from conftest import synthetic_runs, write_csv

BAD_INPUT = 16
WARMING_UP = 1


@pytest.fixture(scope="module")
def runs():
    return synthetic_runs(runs=3)


@pytest.fixture(scope="module")
def model(runs):
    return fogtemp.fit(runs, method="poly", progress=False)


def compensate_warnings(model, time_s, gyro_dph, temp_c):
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        out = model.compensate(time_s, gyro_dph, temp_c)
    return out, [str(w.message) for w in seen if issubclass(w.category, fogtemp.FogtempWarning)]


def test_two_runs_joined_warn_at_the_sample_where_the_time_goes_back(model, runs, tmp_path, cli):
    # Review20 F3: pd.concat of two runs gave no warning; the command line refuses the log at
    # the row where the time goes back (line = index + 2: the header, 1-based lines).
    a, b = runs[0], runs[1]
    joined = {k: np.concatenate([a[k], b[k]]) for k in ("time_s", "temp_c", "gyro_dph")}
    join_index = len(a["time_s"])
    log = tmp_path / "joined.csv"
    write_csv(log, joined)
    model_path = tmp_path / "m.fogm"
    model.save(model_path)
    done = cli("compensate", "--model", model_path, log, "--out", tmp_path / "out.csv")
    assert done.returncode == 1 and f"{log}:{join_index + 2}:1:" in done.stderr, done.stderr
    assert "the time goes back" in done.stderr
    (out, flags), said = compensate_warnings(model, joined["time_s"], joined["gyro_dph"], joined["temp_c"])
    back = [s for s in said if "the time goes back" in s]
    assert len(back) == 1, said
    assert back[0].startswith(f"Model.compensate axis 0: the time goes back at sample {join_index} ("), back[0]
    assert "two runs joined (pd.concat)" in back[0] and "split the arrays at sample" in back[0]
    assert "The compensator restarted there" in back[0]
    # Row for row, and the restart it describes: warming up again right after the join.
    assert len(out) == len(joined["time_s"])
    assert flags[join_index] & WARMING_UP and not flags[join_index - 1] & WARMING_UP


def test_the_warning_counts_every_place_the_time_goes_back(model, runs):
    # Review20 F3: the warning names the first sample where the time goes back and how many
    # more there are. Three runs joined go back twice, at len(a) and len(a) + len(b); a fourth
    # joined run makes it three times.
    parts = [runs[0], runs[1], runs[2]]
    joined = {k: np.concatenate([p[k] for p in parts]) for k in ("time_s", "temp_c", "gyro_dph")}
    first = len(parts[0]["time_s"])
    _, said = compensate_warnings(model, joined["time_s"], joined["gyro_dph"], joined["temp_c"])
    back = [s for s in said if "the time goes back" in s]
    assert len(back) == 1, said
    assert f"the time goes back at sample {first} (" in back[0], back[0]
    assert "), and at 1 more sample: a logger restart" in back[0], back[0]
    parts.append(runs[0])
    joined = {k: np.concatenate([p[k] for p in parts]) for k in ("time_s", "temp_c", "gyro_dph")}
    _, said = compensate_warnings(model, joined["time_s"], joined["gyro_dph"], joined["temp_c"])
    back = [s for s in said if "the time goes back" in s]
    assert len(back) == 1 and "), and at 2 more samples: a logger restart" in back[0], said


def test_one_stamp_back_is_said_to_go_back_not_only_as_a_gap(model, runs):
    run = runs[1]
    t = run["time_s"].copy()
    # One stamp 200 s back (longer than the model's 5 s max gap): a restart. At 5 Hz from
    # 100 s, time_s[2000] = 500 and time_s[2999] = 699.8.
    t[3000] = t[2000]
    (_, flags), said = compensate_warnings(model, t, run["gyro_dph"], run["temp_c"])
    text = " | ".join(said)
    assert "the time goes back at sample 3000: time_s[3000] = 500 is before time_s[2999] = 699.8" in text
    assert "time_s[3001] is after it again: one corrupted stamp?" in text
    assert "the compensator restarted there" in text
    assert "before sample 3001" in text, text  # the gap note: the stamp's step forward
    # One stamp 1 s back (within the max gap): its reading is rejected, flag BAD_INPUT.
    k = 3000  # a sample with a temperature reading (every fifth has one)
    assert not np.isnan(run["temp_c"][k])
    t = run["time_s"].copy()
    t[k] = t[k - 1] - 1.0
    (_, flags), said = compensate_warnings(model, t, run["gyro_dph"], run["temp_c"])
    text = " | ".join(said)
    assert f"the time goes back at sample {k}:" in text and "rejected the temperature readings (flag BAD_INPUT)" in text
    assert flags[k] & BAD_INPUT and not flags[k + 5] & BAD_INPUT
    # Time in order: not a word of it.
    _, said = compensate_warnings(model, run["time_s"], run["gyro_dph"], run["temp_c"])
    assert not any("goes back" in s for s in said), said


def test_temperature_glitches_are_warned_of_as_the_command_line_notes_them(model, runs, tmp_path, cli):
    # Review20 F7: three single-reading +15 C glitches; the command line notes them with their
    # lines, Model.compensate now warns with the same note, naming samples by index.
    run = {k: v.copy() for k, v in runs[1].items()}
    for k in (1000, 3000, 5000):
        assert not np.isnan(run["temp_c"][k])
        run["temp_c"][k] += 15.0
    log = tmp_path / "spikes.csv"
    write_csv(log, run)
    model_path = tmp_path / "m.fogm"
    model.save(model_path)
    done = cli("compensate", "--model", model_path, log, "--out", tmp_path / "out.csv")
    assert done.returncode == 0, done.stderr
    cli_notes = [line[len("note: ") :] for line in done.stderr.splitlines() if "temperature glitch" in line]
    assert len(cli_notes) == 1 and "3 temperature glitches" in cli_notes[0], done.stderr
    # The command line's note with its log lines as sample indices (line = index + 2).
    expected = re.sub(rf"{re.escape(str(log))}:(\d+)", lambda m: f"sample:{int(m[1]) - 2}", cli_notes[0])
    expected = expected.replace(f"{log} axis 0:", "Model.compensate axis 0:", 1)
    assert "sample:1000 " in expected and "sample:5000 " in expected, expected
    data = fogtemp.read_log(log, progress=False)
    _, said = compensate_warnings(model, data["time_s"], data["gyro_dph"], data["temp_c"])
    assert [s for s in said if "temperature glitch" in s] == [expected]
    # Without the glitches: no such warning.
    _, said = compensate_warnings(model, runs[1]["time_s"], runs[1]["gyro_dph"], runs[1]["temp_c"])
    assert not any("temperature glitch" in s for s in said), said


def test_a_nan_gyro_sample_is_named_as_such(model, runs):
    # Review23a F6: a NaN gyro sample (flagged BAD_INPUT, passed through) was blamed on a
    # temperature or a time; the warning now says what it was.
    run = runs[0]
    gyro = run["gyro_dph"].copy()
    gyro[350] = np.nan
    (rate, flags), notes = compensate_warnings(model, run["time_s"], gyro, run["temp_c"])
    assert flags[350] & BAD_INPUT and np.isnan(rate[350])
    bad = [n for n in notes if "BAD_INPUT" in n]
    assert len(bad) == 1, notes
    assert "1 of" in bad[0] and "had a gyro value that is not a number or infinite" in bad[0], bad[0]
    assert "temperature no sensor reads" not in bad[0], bad[0]


def test_samples_in_the_microsecond_of_the_one_before_are_named_as_such(model, runs):
    # Review25a 2/3: times 200 ns after the sample before fall in its microsecond, the
    # compensator's clock, which refuses their temperature readings; the warning names that,
    # as the command line does, and not temperatures no sensor reads.
    run = runs[0]
    time_s, temp_c = run["time_s"].copy(), run["temp_c"].copy()
    # Ten samples 0.2 us apart, each with a reading (the fixture reads every fifth sample).
    time_s[400:410] = time_s[399] + 2e-7 * np.arange(1, 11)
    temp_c[400:410] = temp_c[400]
    (_, flags), notes = compensate_warnings(model, time_s, run["gyro_dph"], temp_c)
    bad = [n for n in notes if "BAD_INPUT" in n]
    assert len(bad) == 1, notes
    refused = int(np.count_nonzero(flags & BAD_INPUT))
    assert refused >= 5 and not flags[400] & BAD_INPUT, refused
    assert f"{refused} of them came in the same microsecond as the last reading taken" in bad[0], bad[0]
    assert "no sensor reads" not in bad[0], bad[0]
