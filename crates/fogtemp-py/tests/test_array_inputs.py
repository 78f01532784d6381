"""Runs given as arrays the way a notebook holds them (pandas columns of every dtype, a dict
of runs keyed by name): read when they are numbers, refused by name when they are not (a
review of the array API, 2026-11-27, found text, booleans and date-times read silently)."""

import numpy as np
import pandas as pd
import pytest

import fogtemp
from conftest import synthetic_runs


@pytest.fixture(scope="module")
def runs():
    return synthetic_runs(seed=11, runs=3)


@pytest.fixture(scope="module")
def model(runs):
    return fogtemp.fit(runs, method="poly", progress=False)


def frame(run):
    return pd.DataFrame({k: run[k] for k in ("time_s", "temp_c", "gyro_dph")})


def test_pandas_text_booleans_and_date_times_are_refused_by_name(model, runs):
    df = frame(runs[0])
    text = df.assign(temp_c=df.temp_c.astype(str))
    with pytest.raises(TypeError, match=r"runs\[0\]\['temp_c'\] must be numbers, got text"):
        fogtemp.validate(model, [text], progress=False)
    with pytest.raises(TypeError, match=r"runs\[0\]\['gyro_dph'\] must be numbers, got text"):
        fogtemp.validate(model, [df.assign(gyro_dph=df.gyro_dph.astype(object).where(df.index != 3, "1.5"))], progress=False)
    boolean = df.assign(gyro_dph=df.gyro_dph.astype(object).where(df.index != 5, True))
    with pytest.raises(TypeError, match=r"must be numbers, got booleans \(element 5: True\)"):
        fogtemp.validate(model, [boolean], progress=False)
    stamps = pd.Timestamp("2024-05-01") + pd.to_timedelta(df.time_s, unit="s")
    for t in (stamps, stamps.dt.tz_localize("UTC"), pd.to_timedelta(df.time_s, unit="s")):
        with pytest.raises(TypeError, match=r"time_s'\] must be numbers, got date-times.*total_seconds"):
            fogtemp.validate(model, [df.assign(time_s=t)], progress=False)
    with pytest.raises(TypeError, match="got date-times"):
        fogtemp.allan(df.assign(time_s=stamps))
    # Numbers of every kind are read: ints, float32, nullable floats (NA is missing).
    for numbers in (df.gyro_dph.astype("float32"), (df.gyro_dph * 100).round().astype("int64")):
        assert fogtemp.validate(model, [df.assign(gyro_dph=numbers)], progress=False)["compensated_bias_stability_dph"] > 0
    nullable = df.assign(temp_c=df.temp_c.astype("Float64"))
    assert fogtemp.validate(model, [nullable], progress=False) == fogtemp.validate(model, [df], progress=False)


def test_float32_times_too_coarse_for_their_steps_are_named(model, runs):
    # At a Unix time (1.7e9 s) float32 keeps 128 s steps: the 0.2 s steps vanish. The row rules
    # would call it a repeated time and suggest skipping; the cause is named instead.
    df = frame(runs[0])
    epoch = df.assign(time_s=(df.time_s + 1.7e9).astype("float32"))
    with pytest.raises(ValueError, match=r"runs\[0\]\['time_s'\] is float32: too coarse for these times"):
        fogtemp.validate(model, [epoch], progress=False)
    # Small float32 times keep their steps and are read.
    small = df.assign(time_s=df.time_s.astype("float32"))
    assert fogtemp.validate(model, [small], progress=False)["compensated_bias_stability_dph"] > 0
    # Model.compensate refuses them alike (review23a F1: it flagged 74 % BAD_INPUT instead).
    with pytest.raises(ValueError, match=r"^time_s is float32: too coarse for these times"):
        model.compensate(epoch.time_s.to_numpy(), epoch.gyro_dph.to_numpy(), epoch.temp_c.to_numpy())
    rate, _ = model.compensate(small.time_s.to_numpy(), small.gyro_dph.to_numpy(), small.temp_c.to_numpy())
    assert len(rate) == len(small)


def test_a_dataframe_without_time_s_is_named_not_taken_for_a_path(model, runs):
    df = frame(runs[0])
    for bad in (df.set_index("time_s"), df.rename(columns={"time_s": "time"})):
        with pytest.raises(ValueError, match=r"runs\[0\]: no 'time_s' .*reset_index\(\) makes it a column"):
            fogtemp.validate(model, [bad], progress=False)
    with pytest.raises(ValueError, match=r"runs\[0\]: temp_c has 10 samples but time_s has"):
        fogtemp.validate(model, [dict(runs[0], temp_c=runs[0]["temp_c"][:10])], progress=False)


def test_a_dict_of_runs_keyed_by_name_names_them_and_paths_do_not_mix(model, runs, tmp_path):
    named = {f"run{k}": frame(r) for k, r in enumerate(runs)}
    doc = fogtemp.validate(model, named, progress=False)
    assert [r["path"] for r in doc["runs"]] == ["run0", "run1", "run2"]
    assert doc["compensated_bias_stability_dph"] == fogtemp.validate(model, runs, progress=False)["compensated_bias_stability_dph"]
    assert fogtemp.fit(named, method="poly", progress=False).inspect()["axes"] == model.inspect()["axes"]
    (tmp_path / "a.csv").write_text("time_s,temp_c,gyro_dph\n0,20,1\n1,20,1\n")
    with pytest.raises(TypeError, match="all logs as paths, or all runs as arrays"):
        fogtemp.fit([tmp_path / "a.csv", runs[1]], progress=False)


def test_diagnose_names_what_it_cannot_pair_or_read(runs):
    named = {f"run{k}": r for k, r in enumerate(runs)}
    with pytest.raises(TypeError, match="not a list: runs are paired by name"):
        fogtemp.diagnose(list(named.values()), named, progress=False)
    with pytest.raises(TypeError, match="simulated is one run"):
        fogtemp.diagnose(runs[0], named, progress=False)
    empty = dict(named, run0={k: v[:0] for k, v in runs[0].items()})
    with pytest.raises(ValueError, match="recorded run run0.csv: no samples"):
        fogtemp.diagnose(named, empty, progress=False)
    with pytest.warns(UserWarning, match="no runs file and no manifest.json .* position and input rate are unknown"):
        fogtemp.diagnose(named, named, progress=False)


def test_the_missing_column_message_names_keys_as_python_writes_them_and_a_rename_that_works(model, runs):
    # Review20 F9: the rename example took the first key (the temperature, for a DataFrame
    # indexed by time), quoted int keys as strings and wrote invalid Python for a MultiIndex.
    df = frame(runs[0])
    with pytest.raises(ValueError) as caught:
        fogtemp.validate(model, [df.set_index("time_s")], progress=False)
    text = str(caught.value)
    assert "it has 'temp_c', 'gyro_dph'; rename, e.g. df.rename(columns={...: 'time_s'})" in text, text
    assert "reset_index() makes it a column" in text
    # A plausible source is named, and following the example reads the run.
    renamed = df.rename(columns={"time_s": "Time (s)"})
    with pytest.raises(ValueError, match=r"df\.rename\(columns=\{'Time \(s\)': 'time_s'\}\)"):
        fogtemp.validate(model, [renamed], progress=False)
    expected = fogtemp.validate(model, [df], progress=False)
    assert fogtemp.validate(model, [renamed.rename(columns={"Time (s)": "time_s"})], progress=False) == expected
    # Int keys as ints, and a dict's own rename.
    numbered = {0: df.time_s.values, 1: df.temp_c.values, 2: df.gyro_dph.values}
    with pytest.raises(ValueError) as caught:
        fogtemp.validate(model, [numbered], progress=False)
    text = str(caught.value)
    assert "it has 0, 1, 2; rename, e.g. run['time_s'] = run.pop(...)" in text and "'0'" not in text, text
    assert "reset_index" not in text
    # MultiIndex columns: a way to one level, which works.
    grouped = pd.concat({"a": df}, axis=1)
    with pytest.raises(ValueError) as caught:
        fogtemp.validate(model, [grouped], progress=False)
    text = str(caught.value)
    assert "it has ('a', 'time_s'), ('a', 'temp_c'), ('a', 'gyro_dph'): the columns are a MultiIndex" in text, text
    assert "df['a'], or drop the outer level with df.droplevel(0, axis=1)" in text
    assert fogtemp.validate(model, [grouped["a"]], progress=False) == expected
    assert fogtemp.validate(model, [grouped.droplevel(0, axis=1)], progress=False) == expected


def test_structured_arrays_and_tuples_are_refused_saying_what_a_run_is(model, runs):
    # Review20 F9: numpy's own errors ("Cannot compare structured or void to non-void arrays",
    # "The truth value of an array ... is ambiguous") said nothing of what a run must be.
    df = frame(runs[0])
    what = r"a run given as arrays must be a dict or a pandas DataFrame keyed by column name, with time_s \(s\)"
    records = df.to_records(index=False)
    with pytest.raises(TypeError, match=what + r".*got a numpy structured array \(fields 'time_s', 'temp_c', 'gyro_dph'\): pandas\.DataFrame\(array\)"):
        fogtemp.fit([records] * 3, method="poly", progress=False)
    # Following the message reads it.
    assert fogtemp.validate(model, [pd.DataFrame(records)], progress=False) == fogtemp.validate(model, [df], progress=False)
    for bad, found in ((tuple(df.values.T), "a tuple"), ([df.time_s.values, df.temp_c.values], "a list"), (df.values, "a numpy array")):
        with pytest.raises(TypeError, match=what + f".*got {found}:"):
            fogtemp.validate(model, [bad], progress=False)
    # diagnose's dict of runs too.
    named = {f"run{k}": r for k, r in enumerate(runs)}
    as_tuples = {name: tuple(r[k] for k in ("time_s", "temp_c", "gyro_dph")) for name, r in named.items()}
    with pytest.raises(TypeError, match=what + ".*got a tuple:"):
        fogtemp.diagnose(as_tuples, named, progress=False)
    # A list of paths in the list of logs keeps the paths' own error.
    with pytest.raises(TypeError, match="must be paths"):
        fogtemp.fit([["a.csv", "b.csv"]], progress=False)


def test_booleans_inside_lists_are_refused_as_in_object_arrays(model, runs):
    # Review20 F10: numpy turned [20.0, True] into [20.0, 1.0] before the dtype check.
    with pytest.raises(TypeError) as as_object:
        model.evaluate(np.array([20.0, True], dtype=object), 0.0)
    assert str(as_object.value) == "temp_c must be numbers, got booleans (element 1: True)"
    for bad in ([20.0, True], (20.0, True), [20.0, np.True_], [[20.0], [True]]):
        with pytest.raises(TypeError) as caught:
            model.evaluate(bad, [0.0, 0.0] if np.ndim(bad) == 1 else [[0.0], [0.0]])
        assert str(caught.value) == str(as_object.value).replace("True", repr(np.asarray(bad, dtype=object).ravel()[1])), bad
    with pytest.raises(TypeError, match=r"rate_c_per_min must be numbers, got booleans \(element 2: False\)"):
        model.evaluate([20.0, 21.0, 22.0], [0, 1, False])
    # The other array-taking calls share the conversion.
    run = runs[0]
    with pytest.raises(TypeError, match=r"gyro_dph must be numbers, got booleans \(element 1: True\)"):
        model.compensate([0.0, 1.0, 2.0], [0.5, True, 0.5], [20.0, 20.0, 20.0])
    bad_run = dict(run, gyro_dph=[float(g) for g in run["gyro_dph"][:-1]] + [False])
    with pytest.raises(TypeError, match=r"runs\[0\]\['gyro_dph'\] must be numbers, got booleans \(element 7499: False\)"):
        fogtemp.validate(model, [bad_run], progress=False)
    # Numbers in lists still read, as before: ints beside floats, numpy scalars.
    assert model.evaluate([20.0, 1], [0, np.float32(0.0)])[1] == model.evaluate(1.0, 0.0)


def test_numbered_axes_as_read_log_returns_them_fit_every_axis(runs):
    # read_log gives gyro_dph_0, gyro_dph_1, ... for a log of several gyro columns: fit takes
    # them as axes, the same model as one 2-D gyro_dph (the oracle); renaming one of them to
    # gyro_dph, as the old error advised, is refused instead of dropping the other (review23a F3).
    def numbered(run):
        return {"time_s": run["time_s"], "temp_c": run["temp_c"],
                "gyro_dph_0": run["gyro_dph"], "gyro_dph_1": 2.0 * run["gyro_dph"]}

    def stacked(run):
        return {"time_s": run["time_s"], "temp_c": run["temp_c"],
                "gyro_dph": np.column_stack([run["gyro_dph"], 2.0 * run["gyro_dph"]])}

    from_numbered = fogtemp.fit([numbered(r) for r in runs], method="poly", progress=False)
    from_stacked = fogtemp.fit([stacked(r) for r in runs], method="poly", progress=False)
    assert from_numbered.axis_count == 2
    assert [a["poly"] for a in from_numbered.inspect()["axes"]] == [a["poly"] for a in from_stacked.inspect()["axes"]]
    renamed = numbered(runs[0])
    renamed["gyro_dph"] = renamed.pop("gyro_dph_0")
    with pytest.raises(ValueError, match=r"both 'gyro_dph' and 'gyro_dph_1'"):
        fogtemp.fit([renamed], method="poly", progress=False)
