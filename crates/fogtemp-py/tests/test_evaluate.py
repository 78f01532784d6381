"""Model.evaluate against independent oracles: scipy's LinearNDInterpolator on the model's own
normalised nodes (mesh), numpy.polynomial on its stored terms (polynomial), and the command
line's `evaluate` (the core's Axis::evaluate, point by point)."""

import numpy as np
import pytest
from numpy.polynomial import polynomial as P
from scipy.interpolate import LinearNDInterpolator

import fogtemp


def normalise(axis, temp_c, rate):
    n = axis["normalisation"]
    x = (temp_c - n["temp_offset_c"]) * n["temp_scale_per_c"]
    y = (rate - n["rate_offset_c_per_min"]) * n["rate_scale_per_c_per_min"]
    return x, y


def random_points_in_range(axis, count, seed):
    p = axis["provenance"]
    rng = np.random.default_rng(seed)
    temp = rng.uniform(p["temp_min_c"], p["temp_max_c"], count)
    rate = rng.uniform(p["rate_min_c_per_min"], p["rate_max_c_per_min"], count)
    return temp, rate


def test_mesh_matches_scipy_linear_interpolation_on_the_nodes(mesh_model):
    axis = mesh_model.inspect()["axes"][0]
    assert axis["kind"] == ["mesh"]
    nodes = axis["nodes"]
    assert len(nodes) >= 10
    xy = np.array([[n["x"], n["y"]] for n in nodes])
    values = np.array([n["value_dph"] for n in nodes])
    scipy_interp = LinearNDInterpolator(xy, values)
    temp, rate = random_points_in_range(axis, 200_000, seed=11)
    ours = mesh_model.evaluate(temp, rate)
    x, y = normalise(axis, temp, rate)
    theirs = scipy_interp(x, y)
    inside = np.isfinite(theirs)
    assert inside.sum() > 50_000  # most of the calibrated box lies inside the hull
    span = values.max() - values.min()
    worst = np.max(np.abs(ours[inside] - theirs[inside]))
    assert worst <= 1e-4 * span, (worst, span)


def test_polynomial_matches_numpy_polynomial_on_the_terms(cal_logs, poly_model):
    # Extrapolated everywhere, so every point of the box is the terms' own value; the
    # default (linear from the calibrated region's boundary) agrees with it inside the region.
    extrapolated = fogtemp.fit(cal_logs, method="poly", poly_outside="extrapolate", progress=False)
    axis = extrapolated.inspect()["axes"][0]
    assert axis["kind"] == ["poly"] and axis["poly_outside"] == "extrapolate"
    assert poly_model.inspect()["axes"][0]["poly_outside"] == "linear_from_boundary"
    terms = axis["poly"]
    degree = max(max(t["temp_power"], t["rate_power"]) for t in terms)
    coefficients = np.zeros((degree + 1, degree + 1))
    for t in terms:
        coefficients[t["temp_power"], t["rate_power"]] += t["coefficient_dph"]
    temp, rate = random_points_in_range(axis, 100_000, seed=12)
    x, y = normalise(axis, temp, rate)
    theirs = P.polyval2d(x, y, coefficients)
    ours = extrapolated.evaluate(temp, rate)
    span = theirs.max() - theirs.min()
    worst = np.max(np.abs(ours - theirs))
    # The core evaluates in f32: a relative error of a few 1e-7 of the terms' magnitudes.
    assert worst <= 1e-4 * span, (worst, span)
    # Same terms, so the default model equals the extrapolated one bit for bit wherever the
    # compensator does not flag OUTSIDE_HULL (inside the region), and differs beyond it.
    default = poly_model.evaluate(temp, rate)
    same = default == ours
    # A polynomial in T alone is calibrated over the box of its ranges (review21 F1): the
    # points drawn in that box are all inside its region.
    t_alone = all(t["rate_power"] == 0 for t in terms)
    assert 0 < same.sum() and (same.all() if t_alone else same.sum() < same.size), same.sum()


def test_any_shape_broadcasting_and_nan(mesh_model):
    temp = np.linspace(-30.0, 50.0, 24).reshape(2, 3, 4)
    rate = np.float64(0.1)
    out = mesh_model.evaluate(temp, rate)
    assert out.shape == (2, 3, 4) and out.dtype == np.float64
    flat = mesh_model.evaluate(temp.ravel(), np.full(24, 0.1))
    np.testing.assert_array_equal(out.ravel(), flat)
    assert type(mesh_model.evaluate(20.0, 0.0)) is float  # scalars in, a float out
    assert mesh_model.evaluate([20.0, 21.0], [0.0, 0.0]).shape == (2,)
    with_nan = mesh_model.evaluate([20.0, np.nan, 21.0], [0.0, 0.0, np.inf])
    assert np.isfinite(with_nan[0]) and np.isnan(with_nan[1]) and np.isnan(with_nan[2])
    # A Fortran-ordered, strided view gives the same values as its contiguous copy.
    strided = np.asfortranarray(np.linspace(-30, 50, 200).reshape(10, 20))[:, ::3]
    np.testing.assert_array_equal(
        mesh_model.evaluate(strided, 0.05), mesh_model.evaluate(np.ascontiguousarray(strided), 0.05)
    )


def test_threads_and_start_grid_agree_with_the_command_line(mesh_model, tmp_path, cli):
    axis = mesh_model.inspect()["axes"][0]
    temp, rate = random_points_in_range(axis, 100_000, seed=13)
    # Points outside the calibrated box too (the outside-hull policy).
    temp = np.concatenate([temp, [-80.0, 120.0]])
    rate = np.concatenate([rate, [3.0, -3.0]])
    model_path = tmp_path / "m.fogm"
    mesh_model.save(model_path)
    points = tmp_path / "points.csv"
    with open(points, "w") as f:
        f.write("temp_c,rate_c_per_min\n")
        for t, r in zip(temp, rate):
            f.write(f"{float(t)!r},{float(r)!r}\n")
    out = tmp_path / "out.csv"
    done = cli("evaluate", "--model", model_path, "--points", points, "--out", out)
    assert done.returncode == 0, done.stderr
    cli_values = np.loadtxt(out, delimiter=",", skiprows=1, usecols=2)
    one_thread = mesh_model.evaluate(temp, rate, threads=1)
    many = mesh_model.evaluate(temp, rate, threads=4)
    np.testing.assert_array_equal(one_thread, many)
    # The grid start may end in the neighbouring triangle for a point on a shared edge: the two
    # planes agree there to f32 rounding.
    np.testing.assert_allclose(one_thread, cli_values, rtol=0, atol=1e-5)


def test_non_finite_points_of_a_large_input_give_nan_and_leave_the_others_alone(mesh_model):
    # A large input (start grid, two passes per block): NaN exactly at the non-finite points,
    # every other value bit for bit the value without them.
    axis = mesh_model.inspect()["axes"][0]
    temp, rate = random_points_in_range(axis, 50_000, seed=17)
    temp = np.concatenate([temp, [-80.0, 120.0]])
    rate = np.concatenate([rate, [3.0, -3.0]])
    clean = mesh_model.evaluate(temp, rate, threads=1)
    bad = np.zeros(temp.size, dtype=bool)
    bad[::997] = True
    spoiled_temp = np.where(bad, np.nan, temp)
    spoiled_rate = np.where(np.roll(bad, 1), np.inf, rate)
    spoiled = mesh_model.evaluate(spoiled_temp, spoiled_rate, threads=1)
    hit = bad | np.roll(bad, 1)
    assert np.isnan(spoiled[hit]).all()
    np.testing.assert_array_equal(spoiled[~hit], clean[~hit])
    assert np.isfinite(clean).all()


def test_axis_out_of_range_is_a_value_error(mesh_model):
    with pytest.raises(ValueError, match="axis 3 does not exist"):
        mesh_model.evaluate(20.0, 0.0, axis=3)


def test_mesh_outside_is_an_option_and_acts_only_outside_the_hull(cal_logs, mesh_model):
    # The default continues the mesh linearly with gradients stored per hull vertex; "hold"
    # holds the hull value, "linear_from_boundary" fits the gradient at query time. Inside the
    # hull all are the same interpolation bit for bit; beyond it they differ.
    stored = mesh_model
    held = fogtemp.fit(cal_logs, method="mesh", mesh_outside="hold", progress=False)
    linear = fogtemp.fit(cal_logs, method="mesh", mesh_outside="linear_from_boundary", progress=False)
    assert stored.inspect()["axes"][0]["outside_policy"] == "linear_stored_gradients"
    assert held.inspect()["axes"][0]["outside_policy"] == "nearest_hull"
    assert linear.inspect()["axes"][0]["outside_policy"] == "linear_from_boundary"
    axis = linear.inspect()["axes"][0]
    temp, rate = random_points_in_range(axis, 20_000, seed=13)
    xy = np.array([[v["x"], v["y"]] for v in axis["nodes"]])
    inside = np.isfinite(LinearNDInterpolator(xy, np.zeros(len(xy)))(*normalise(axis, temp, rate)))
    ours, theirs, kept = linear.evaluate(temp, rate), held.evaluate(temp, rate), stored.evaluate(temp, rate)
    # Away from the hull's edge (scipy and the core may disagree within rounding on it).
    assert inside.sum() > 1000 and (~inside).sum() > 100
    assert np.mean(ours[inside] == theirs[inside]) > 0.99
    assert np.mean(kept[inside] == theirs[inside]) > 0.99
    assert np.any(ours[~inside] != theirs[~inside])
    assert np.any(kept[~inside] != theirs[~inside])
    with pytest.raises(ValueError, match="mesh_outside"):
        fogtemp.fit(cal_logs, method="mesh", mesh_outside="sideways", progress=False)


def test_scalar_inputs_give_a_python_float(mesh_model):
    # Scalars (Python, numpy or 0-d arrays) in, a float out, as numpy's ufuncs do; anything
    # with a dimension keeps its broadcast shape.
    expected = mesh_model.evaluate(np.array([20.0]), np.array([0.1]))[0]
    for t, r in [(20.0, 0.1), (np.float64(20.0), np.float32(0.1)), (np.array(20.0), 0.1), (20, np.array(0.1))]:
        value = mesh_model.evaluate(t, r)
        assert type(value) is float
        assert value == expected
    nan = mesh_model.evaluate(float("nan"), 0.1)
    assert type(nan) is float and np.isnan(nan)
    assert mesh_model.evaluate([20.0], 0.1).shape == (1,)
    assert mesh_model.evaluate(20.0, np.array([[0.1, 0.2]])).shape == (1, 2)


def test_threads_beyond_the_cores_are_capped(mesh_model):
    # Review20 F12: threads=100000 spawned that many threads (and ran 7x slower). Oracle: the
    # process's thread count (Linux /proc), sampled while the evaluation runs with the GIL
    # released, never exceeds what it was by more than the cores.
    import os
    import threading

    status = "/proc/self/status"
    if not os.path.exists(status):
        pytest.skip("needs /proc")

    def threads_now():
        with open(status) as f:
            return next(int(line.split()[1]) for line in f if line.startswith("Threads:"))

    rng = np.random.default_rng(3)
    temp, rate = rng.uniform(-30.0, 60.0, 1_000_000), rng.uniform(-1.0, 1.0, 1_000_000)
    result = {}
    worker = threading.Thread(target=lambda: result.setdefault("values", mesh_model.evaluate(temp, rate, threads=100_000)))
    before = threads_now()
    worker.start()
    most = before
    while worker.is_alive():
        most = max(most, threads_now())
    worker.join()
    assert most - before <= (os.cpu_count() or 1) + 2, (before, most)  # + this test's worker thread, + slack
    np.testing.assert_array_equal(result["values"], mesh_model.evaluate(temp, rate, threads=1))
    assert "capped" in fogtemp.Model.evaluate.__doc__
