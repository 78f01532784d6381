//! One run: the deterministic truth on the thermal grid, then samples at the gyro rate.

use rand::{Rng, SeedableRng};
use rand_distr::StandardNormal;
use rand_xoshiro::Xoshiro256PlusPlus;

use super::noise::NoiseGenerator;
use super::scenario::{BiasParams, InitialState, Node, RunSpec, Scenario};
use super::thermal::{node_temp_c, State, ThermalModel, CASE, COIL_INNER, COIL_OUTER, ELECTRONICS, SENSOR};

/// The deterministic state of a run at one thermal grid time.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TruthPoint {
    /// Seconds since power-on.
    pub time_s: f64,
    /// Chamber air, deg C.
    pub ambient_c: f64,
    /// Electronics, deg C.
    pub electronics_c: f64,
    /// Case, deg C.
    pub case_c: f64,
    /// Coil (mean of its layers), deg C.
    pub coil_c: f64,
    /// Sensor's true temperature (before noise and quantisation), deg C.
    pub sensor_c: f64,
    /// The temperature that drives the bias, deg C.
    pub bias_temp_c: f64,
    /// dT_coil/dt, deg C/min.
    pub coil_rate_c_per_min: f64,
    /// Coil radial gradient T_outer - T_inner, deg C.
    pub gradient_c: f64,
    /// Its rate, deg C/min.
    pub gradient_rate_c_per_min: f64,
    /// Dissipated power, W.
    pub power_w: f64,
    /// Deterministic gyro output: input rate times scale factor plus every bias term, deg/h.
    pub output_dph: f64,
    /// The bias part alone (what a compensation should remove, Earth rate excluded), deg/h.
    pub bias_dph: f64,
}

/// The deterministic part of a run.
#[derive(Clone, Debug, PartialEq)]
pub struct RunTruth {
    /// The run.
    pub spec: RunSpec,
    /// Earth rate on the input axis, deg/h.
    pub input_rate_dph: f64,
    /// This run's turn-on bias (drawn from its random stream), deg/h.
    pub turn_on_dph: f64,
    /// The thermal grid, from 0 to at least the run's duration.
    pub points: Vec<TruthPoint>,
}

/// One logged sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    /// Seconds since power-on.
    pub time_s: f64,
    /// Logged temperature (held between sensor samples), deg C.
    pub temp_c: f64,
    /// Gyro output, deg/h.
    pub gyro_dph: f64,
}

/// The random streams of a run: one for the gyro, one for the temperature sensor, both
/// derived from the scenario seed and the run's name (so adding a run changes no other).
pub fn run_rngs(seed: u64, name: &str) -> (Xoshiro256PlusPlus, Xoshiro256PlusPlus) {
    // FNV-1a of the name, mixed with the seed.
    let mut hash = 0xcbf2_9ce4_8422_2325_u64;
    for byte in name.bytes() {
        hash = (hash ^ u64::from(byte)).wrapping_mul(0x0000_0100_0000_01b3);
    }
    let gyro = Xoshiro256PlusPlus::seed_from_u64(seed ^ hash);
    let mut sensor = gyro.clone();
    sensor.jump();
    (gyro, sensor)
}

/// Total chamber air temperature at `t_s`: the profile plus the control ripple.
fn ambient_c(scenario: &Scenario, spec: &RunSpec, t_s: f64) -> f64 {
    spec.chamber.temp_c(t_s) + ripple_c(scenario, t_s)
}

/// The chamber air temperature just before `t_s` (differs from [`ambient_c`] only at a step).
fn ambient_before_c(scenario: &Scenario, spec: &RunSpec, t_s: f64) -> f64 {
    spec.chamber.temp_before_c(t_s) + ripple_c(scenario, t_s)
}

fn ripple_c(scenario: &Scenario, t_s: f64) -> f64 {
    let ripple = &scenario.chamber;
    if ripple.ripple_amplitude_c > 0.0 {
        ripple.ripple_amplitude_c * (std::f64::consts::TAU * t_s / ripple.ripple_period_s).sin()
    } else {
        0.0
    }
}

/// The bias terms at one grid point (deg/h), Earth rate excluded.
fn bias_dph(p: &BiasParams, tp: &TruthPoint, turn_on_dph: f64) -> f64 {
    let dt = tp.bias_temp_c - p.reference_temp_c;
    let static_dph = p.static_dph.iter().rev().fold(0.0, |acc, c| acc * dt + c);
    let ripple =
        p.static_ripple_dph * (std::f64::consts::TAU * tp.bias_temp_c / p.static_ripple_period_c).sin();
    let warmup = p.warmup_amplitude_dph * (-tp.time_s / p.warmup_time_constant_s).exp();
    let hysteresis = p.hysteresis_dph * (tp.coil_rate_c_per_min / p.hysteresis_rate_c_per_min).tanh();
    let cycling = p.cycling_dph * (std::f64::consts::TAU * tp.time_s / p.cycling_period_s).sin();
    static_dph
        + ripple
        + p.shupe_dph_per_c_per_min * tp.coil_rate_c_per_min
        + p.gradient_dph_per_c * tp.gradient_c
        + p.gradient_rate_dph_per_c_per_min * tp.gradient_rate_c_per_min
        + warmup
        + hysteresis
        + cycling
        + turn_on_dph
}

/// Scale-factor error at temperature `temp_c`, as a fraction.
fn scale_factor_error(p: &BiasParams, temp_c: f64) -> f64 {
    1e-6 * (p.scale_factor_ppm + p.scale_factor_ppm_per_c * (temp_c - p.reference_temp_c))
}

/// The deterministic truth of `spec` on the thermal grid (exact steps of `thermal.step_s`).
pub fn run_truth(scenario: &Scenario, spec: &RunSpec) -> RunTruth {
    let model = ThermalModel::new(&scenario.thermal, &scenario.sensor);
    let (mut gyro_rng, _) = run_rngs(scenario.seed, &spec.name);
    let turn_on_dph = scenario.bias.turn_on_sigma_dph * gyro_rng.sample::<f64, _>(StandardNormal);
    let input_rate_dph = spec.input_axis.earth_rate_dph(&scenario.site);
    let h = model.step_s();
    let steps = (spec.duration_s / h).ceil() as usize + 1;
    let mut x: State = match spec.initial {
        InitialState::Soaked => ThermalModel::soaked(ambient_c(scenario, spec, 0.0)),
        InitialState::Warm => model.warm(ambient_c(scenario, spec, 0.0)),
    };
    let mut points = Vec::with_capacity(steps + 1);
    for k in 0..=steps {
        let t = k as f64 * h;
        let ta = ambient_c(scenario, spec, t);
        // The step moves the chamber linearly from ta to ta_next; at a chamber step at t + h
        // that must be the value before it (the new value starts the next interval), or the
        // step would be spread over [t, t + h] and arrive half a step early.
        let ta_next = ambient_before_c(scenario, spec, t + h);
        let power_w = model.power_w(&x);
        let dx = model.derivative(&x, power_w, ta);
        let mut tp = TruthPoint {
            time_s: t,
            ambient_c: ta,
            electronics_c: x[ELECTRONICS],
            case_c: x[CASE],
            coil_c: node_temp_c(&x, Node::Coil),
            sensor_c: x[SENSOR],
            bias_temp_c: node_temp_c(&x, scenario.bias.temperature_node),
            coil_rate_c_per_min: 60.0 * 0.5 * (dx[COIL_OUTER] + dx[COIL_INNER]),
            gradient_c: x[COIL_OUTER] - x[COIL_INNER],
            gradient_rate_c_per_min: 60.0 * (dx[COIL_OUTER] - dx[COIL_INNER]),
            power_w,
            output_dph: 0.0,
            bias_dph: 0.0,
        };
        tp.bias_dph = bias_dph(&scenario.bias, &tp, turn_on_dph);
        tp.output_dph =
            input_rate_dph * (1.0 + scale_factor_error(&scenario.bias, tp.bias_temp_c)) + tp.bias_dph;
        points.push(tp);
        x = model.step(&x, power_w, ta, ta_next);
    }
    RunTruth { spec: spec.clone(), input_rate_dph, turn_on_dph, points }
}

impl RunTruth {
    /// Linear interpolation of `field` at `t_s` on the grid (clamped to its ends).
    pub fn at(&self, t_s: f64, field: impl Fn(&TruthPoint) -> f64) -> f64 {
        let Some(first) = self.points.first() else { return f64::NAN };
        let h = self.points.get(1).map_or(1.0, |p| p.time_s - first.time_s);
        let pos = ((t_s - first.time_s) / h).max(0.0);
        let k = (pos.floor() as usize).min(self.points.len().saturating_sub(2));
        match (self.points.get(k), self.points.get(k + 1)) {
            (Some(a), Some(b)) => {
                let f = (pos - k as f64).clamp(0.0, 1.0);
                field(a) + f * (field(b) - field(a))
            }
            (Some(a), None) => field(a),
            _ => f64::NAN,
        }
    }
}

/// Produces a run's samples in time order.
pub struct RunGenerator<'a> {
    truth: &'a RunTruth,
    rate_hz: f64,
    total: u64,
    index: u64,
    grid_step_s: f64,
    noise: NoiseGenerator,
    gyro_rng: Xoshiro256PlusPlus,
    sensor_rng: Xoshiro256PlusPlus,
    sensor_rate_hz: f64,
    /// Index of the next sensor sample (due at `sensor_index / sensor_rate_hz`).
    sensor_index: u64,
    sensor_noise_c: f64,
    sensor_quantum_c: f64,
    sensor_offset_c: f64,
    logged_temp_c: f64,
    angle_lsb_deg: f64,
    angle_deg: f64,
    counts: f64,
}

impl<'a> RunGenerator<'a> {
    /// Samples of `truth` at the scenario's rate, `floor(duration * rate) + 1` of them.
    pub fn new(scenario: &Scenario, truth: &'a RunTruth) -> Self {
        let (mut gyro_rng, sensor_rng) = run_rngs(scenario.seed, &truth.spec.name);
        // The first draw of the gyro stream is the turn-on bias (see run_truth).
        let _turn_on: f64 = gyro_rng.sample(StandardNormal);
        let rate_hz = scenario.sample_rate_hz;
        let noise = NoiseGenerator::new(&scenario.noise, rate_hz, &mut gyro_rng);
        let grid_step_s = truth.points.get(1).map_or(1.0, |p| p.time_s);
        Self {
            truth,
            rate_hz,
            total: (truth.spec.duration_s * rate_hz).floor() as u64 + 1,
            index: 0,
            grid_step_s,
            noise,
            gyro_rng,
            sensor_rng,
            sensor_rate_hz: scenario.sensor.rate_hz,
            sensor_index: 0,
            sensor_noise_c: scenario.sensor.noise_c,
            sensor_quantum_c: scenario.sensor.quantum_c,
            sensor_offset_c: scenario.sensor.offset_c,
            logged_temp_c: f64::NAN,
            angle_lsb_deg: scenario.noise.angle_lsb_arcsec / 3600.0,
            angle_deg: 0.0,
            counts: 0.0,
        }
    }

    /// Number of samples the run has.
    pub fn len(&self) -> u64 {
        self.total
    }

    /// True when the run has no samples (never for a valid scenario).
    pub fn is_empty(&self) -> bool {
        self.total == 0
    }

    fn interpolate(&self, t_s: f64, field: impl Fn(&TruthPoint) -> f64) -> f64 {
        let pos = t_s / self.grid_step_s;
        let k = pos as usize;
        let points = &self.truth.points;
        match (points.get(k), points.get(k + 1)) {
            (Some(a), Some(b)) => {
                let f = pos - k as f64;
                field(a) + f * (field(b) - field(a))
            }
            _ => self.truth.at(t_s, field),
        }
    }

    fn read_sensor(&mut self, t_s: f64) {
        // Sensor times are computed as index / rate, like the gyro's, never accumulated: a
        // sum of periods drifts (0.1 + 0.1 + 0.1 > 0.3) and would skip the sensor sample due
        // at the same instant as a gyro sample, logging the previous one for a gyro period.
        loop {
            let t = self.sensor_index as f64 / self.sensor_rate_hz;
            if t > t_s {
                break;
            }
            let mut reading = self.interpolate(t, |p| p.sensor_c) + self.sensor_offset_c;
            if self.sensor_noise_c > 0.0 {
                reading += self.sensor_noise_c * self.sensor_rng.sample::<f64, _>(StandardNormal);
            }
            if self.sensor_quantum_c > 0.0 {
                reading = (reading / self.sensor_quantum_c).round() * self.sensor_quantum_c;
            }
            self.logged_temp_c = reading;
            self.sensor_index += 1;
        }
    }

    fn quantise(&mut self, rate_dph: f64) -> f64 {
        if self.angle_lsb_deg <= 0.0 {
            return rate_dph;
        }
        let dt_s = 1.0 / self.rate_hz;
        self.angle_deg += rate_dph / 3600.0 * dt_s;
        let counts = (self.angle_deg / self.angle_lsb_deg).floor();
        let out = (counts - self.counts) * self.angle_lsb_deg * 3600.0 / dt_s;
        self.counts = counts;
        out
    }
}

impl Iterator for RunGenerator<'_> {
    type Item = Sample;

    fn next(&mut self) -> Option<Sample> {
        if self.index >= self.total {
            return None;
        }
        let t_s = self.index as f64 / self.rate_hz;
        self.index += 1;
        self.read_sensor(t_s);
        let deterministic = self.interpolate(t_s, |p| p.output_dph);
        let noise = self.noise.next(&mut self.gyro_rng);
        let gyro_dph = self.quantise(deterministic + noise);
        Some(Sample { time_s: t_s, temp_c: self.logged_temp_c, gyro_dph })
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        let left = usize::try_from(self.total - self.index).unwrap_or(usize::MAX);
        (left, Some(left))
    }
}
