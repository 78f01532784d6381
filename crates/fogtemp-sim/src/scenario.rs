//! The scenario file (TOML): protocol, thermal network, bias physics, noise, temperature
//! sensor, sample rate and seed. The built-in `paper` scenario lives in `paper.toml` beside
//! this file, with the source of every parameter written next to it.

use serde::{Deserialize, Serialize};

use crate::error::SimError;

/// The built-in scenario of the paper's experiment, with its sources as comments.
pub const PAPER_TOML: &str = include_str!("paper.toml");

/// A whole simulated experiment.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    /// Name, used in reports.
    pub name: String,
    /// Gyro output rate, Hz.
    pub sample_rate_hz: f64,
    /// Seed of every random stream (each run derives its own stream from it and its index).
    pub seed: u64,
    /// Where the lab is.
    pub site: Site,
    /// The lumped thermal network and self-heating.
    pub thermal: ThermalParams,
    /// The temperature sensor that is logged.
    pub sensor: SensorParams,
    /// Deterministic bias physics.
    pub bias: BiasParams,
    /// Random errors.
    pub noise: NoiseParams,
    /// Chamber imperfections shared by every run.
    #[serde(default)]
    pub chamber: ChamberParams,
    /// A grid of runs: every start temperature at every position (expanded before `runs`).
    #[serde(default)]
    pub grid: Option<RunGrid>,
    /// Explicit runs (after the grid's).
    #[serde(default)]
    pub runs: Vec<RunSpec>,
}

/// The lab's location.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Site {
    /// Geodetic latitude, degrees north.
    pub latitude_deg: f64,
    /// Earth's rotation rate, deg/h.
    #[serde(default = "default_earth_rate_dph")]
    pub earth_rate_dph: f64,
}

fn default_earth_rate_dph() -> f64 {
    // 7.292115e-5 rad/s in deg/h (docs/physics.md section 1, WGS-84 value).
    7.292_115e-5_f64.to_degrees() * 3600.0
}

/// Which node's temperature a quantity follows.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Node {
    /// Electronics board.
    Electronics,
    /// Case (housing).
    Case,
    /// Fibre coil (mean of its outer and inner layers).
    Coil,
    /// The logged temperature sensor itself.
    Sensor,
}

/// The lumped thermal network (docs/physics.md section 2): electronics -> case -> coil outer
/// layer -> coil inner layer, case -> ambient (chamber), and a sensor with its own lag on a
/// mount node. Power after power-on: `P = power_w + tec_w_per_k*|T_e - tec_setpoint_c| +
/// heater_w*[T_e < heater_below_c]`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ThermalParams {
    /// C_e, J/K.
    pub electronics_heat_capacity_j_per_k: f64,
    /// C_c, J/K.
    pub case_heat_capacity_j_per_k: f64,
    /// C_o, J/K.
    pub coil_outer_heat_capacity_j_per_k: f64,
    /// C_i, J/K.
    pub coil_inner_heat_capacity_j_per_k: f64,
    /// G_ec, W/K.
    pub electronics_case_w_per_k: f64,
    /// G_co, W/K.
    pub case_coil_w_per_k: f64,
    /// G_oi (radial conductance through the coil), W/K.
    pub coil_radial_w_per_k: f64,
    /// G_ca (case to chamber air), W/K.
    pub case_ambient_w_per_k: f64,
    /// P_0 after power-on, W.
    pub power_w: f64,
    /// k_TEC: extra power per kelvin of |T_e - tec_setpoint_c|, W/K (0: no TEC).
    #[serde(default)]
    pub tec_w_per_k: f64,
    /// TEC set point, deg C.
    #[serde(default = "default_setpoint_c")]
    pub tec_setpoint_c: f64,
    /// Heater power while the electronics are colder than `heater_below_c`, W (0: none).
    #[serde(default)]
    pub heater_w: f64,
    /// Heater threshold, deg C.
    #[serde(default = "default_heater_below_c")]
    pub heater_below_c: f64,
    /// Integration step of the exact discrete thermal update, s.
    #[serde(default = "default_thermal_step_s")]
    pub step_s: f64,
}

fn default_setpoint_c() -> f64 {
    25.0
}
fn default_heater_below_c() -> f64 {
    -20.0
}
fn default_thermal_step_s() -> f64 {
    1.0
}

/// The logged temperature sensor: a first-order lag on its mount node, sampled, noisy,
/// quantised, held between samples in the log.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SensorParams {
    /// The node the sensor sits on.
    pub mount: Node,
    /// Sensor lag tau_s, s.
    pub time_constant_s: f64,
    /// Sampling rate, Hz (the log holds the last sample).
    pub rate_hz: f64,
    /// White noise, deg C (1 sigma).
    pub noise_c: f64,
    /// Quantisation step, deg C (0: none).
    pub quantum_c: f64,
    /// Constant offset error, deg C.
    #[serde(default)]
    pub offset_c: f64,
}

/// Deterministic bias physics. All terms in deg/h; the gyro reads
/// `(1 + sf(T_b)) * Omega_in + bias + noise`, with `T_b` the temperature of `temperature_node`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BiasParams {
    /// Which temperature drives the bias (`coil`: the coil lags the sensor, the normal case;
    /// `sensor`: no lag, the assumption of a model without `thermal_lag`).
    pub temperature_node: Node,
    /// Reference temperature of the polynomials, deg C.
    pub reference_temp_c: f64,
    /// Static b(T) = sum_i `static_dph[i]` * (T - ref)^i, deg/h per deg C^i.
    pub static_dph: Vec<f64>,
    /// Shupe term S1 on the coil's dT/dt, deg/h per (deg C/min).
    pub shupe_dph_per_c_per_min: f64,
    /// Radial-gradient term S2 on (T_outer - T_inner), deg/h per deg C.
    #[serde(default)]
    pub gradient_dph_per_c: f64,
    /// Term S3 on d(T_outer - T_inner)/dt, deg/h per (deg C/min).
    #[serde(default)]
    pub gradient_rate_dph_per_c_per_min: f64,
    /// Warm-up transient not driven by temperature: amplitude at power-on, deg/h.
    #[serde(default)]
    pub warmup_amplitude_dph: f64,
    /// Its time constant, s.
    #[serde(default = "default_warmup_tau_s")]
    pub warmup_time_constant_s: f64,
    /// Hysteresis: +h while heating, -h while cooling (smoothed sign), deg/h.
    #[serde(default)]
    pub hysteresis_dph: f64,
    /// The rate that saturates the smoothed sign, deg C/min.
    #[serde(default = "default_hysteresis_rate")]
    pub hysteresis_rate_c_per_min: f64,
    /// Quasi-periodic structure in b(T) (polarisation non-reciprocity), amplitude, deg/h.
    #[serde(default)]
    pub static_ripple_dph: f64,
    /// Its period in temperature, deg C.
    #[serde(default = "default_ripple_period_c")]
    pub static_ripple_period_c: f64,
    /// Scale-factor error at the reference temperature, ppm.
    #[serde(default)]
    pub scale_factor_ppm: f64,
    /// Scale-factor temperature coefficient, ppm per deg C.
    #[serde(default)]
    pub scale_factor_ppm_per_c: f64,
    /// Turn-on bias repeatability: a constant drawn per run, deg/h (1 sigma).
    #[serde(default)]
    pub turn_on_sigma_dph: f64,
    /// Supply / compressor cycling seen by the gyro: amplitude, deg/h.
    #[serde(default)]
    pub cycling_dph: f64,
    /// Its period, s.
    #[serde(default = "default_cycling_period_s")]
    pub cycling_period_s: f64,
}

fn default_warmup_tau_s() -> f64 {
    600.0
}
fn default_hysteresis_rate() -> f64 {
    0.01
}
fn default_ripple_period_c() -> f64 {
    20.0
}
fn default_cycling_period_s() -> f64 {
    900.0
}

/// Random errors (IEEE Std 952 terms).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NoiseParams {
    /// Angle random walk N, deg/sqrt(h).
    pub arw_deg_per_sqrt_h: f64,
    /// Bias instability B, deg/h (flicker floor = 0.664 B), as a sum of Gauss-Markov terms.
    pub bias_instability_dph: f64,
    /// Shortest Gauss-Markov correlation time, s (one term per decade).
    #[serde(default = "default_flicker_min_s")]
    pub flicker_tau_min_s: f64,
    /// Longest Gauss-Markov correlation time, s.
    #[serde(default = "default_flicker_max_s")]
    pub flicker_tau_max_s: f64,
    /// Rate random walk K, deg/h/sqrt(h).
    #[serde(default)]
    pub rrw_dph_per_sqrt_h: f64,
    /// Output quantisation: angle per count, arcsec (0: none).
    #[serde(default)]
    pub angle_lsb_arcsec: f64,
}

fn default_flicker_min_s() -> f64 {
    0.1
}
fn default_flicker_max_s() -> f64 {
    1.0e5
}

/// Chamber imperfections.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ChamberParams {
    /// Control ripple amplitude, deg C.
    #[serde(default)]
    pub ripple_amplitude_c: f64,
    /// Its period, s.
    #[serde(default)]
    pub ripple_period_s: f64,
}

/// The chamber's set temperature over a run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum ChamberProfile {
    /// Constant.
    Constant {
        /// deg C.
        temp_c: f64,
    },
    /// Hold `start_c` until `start_s`, then ramp at `rate_c_per_min` until `end_c`, then hold.
    Ramp {
        /// deg C.
        start_c: f64,
        /// deg C.
        end_c: f64,
        /// deg C/min (magnitude; the sign follows end - start).
        rate_c_per_min: f64,
        /// s.
        #[serde(default)]
        start_s: f64,
    },
    /// `start_c`, then `to_c` from `at_s` on (the chamber's own response is not modelled).
    /// The thermal solution is exact for a step at a multiple of `thermal.step_s`; a step
    /// between grid times is spread linearly over the step that contains it.
    Step {
        /// deg C.
        start_c: f64,
        /// deg C.
        to_c: f64,
        /// s.
        at_s: f64,
    },
    /// mean + amplitude * sin(2 pi t / period).
    Sinusoid {
        /// deg C.
        mean_c: f64,
        /// deg C.
        amplitude_c: f64,
        /// s.
        period_s: f64,
    },
    /// Piecewise linear through `(time_s, temp_c)` points, held outside them; two points at
    /// the same time make a step (the second value from that time on).
    Points {
        /// `[time_s, temp_c]` pairs with increasing time.
        points: Vec<[f64; 2]>,
    },
}

impl ChamberProfile {
    /// Set temperature at `t_s`, deg C.
    pub fn temp_c(&self, t_s: f64) -> f64 {
        match self {
            Self::Constant { temp_c } => *temp_c,
            Self::Ramp { start_c, end_c, rate_c_per_min, start_s } => {
                let span = end_c - start_c;
                let moved = (t_s - start_s).max(0.0) * rate_c_per_min.abs() / 60.0;
                start_c + span.signum() * moved.min(span.abs())
            }
            Self::Step { start_c, to_c, at_s } => {
                if t_s < *at_s {
                    *start_c
                } else {
                    *to_c
                }
            }
            Self::Sinusoid { mean_c, amplitude_c, period_s } => {
                mean_c + amplitude_c * (std::f64::consts::TAU * t_s / period_s).sin()
            }
            Self::Points { points } => piecewise(points, t_s, false),
        }
    }

    /// The limit of [`Self::temp_c`] from the left at `t_s` (equal to it except at a step):
    /// the chamber temperature at the end of an interval that ends at `t_s`.
    pub fn temp_before_c(&self, t_s: f64) -> f64 {
        match self {
            Self::Step { start_c, to_c, at_s } => {
                if t_s <= *at_s {
                    *start_c
                } else {
                    *to_c
                }
            }
            Self::Points { points } => piecewise(points, t_s, true),
            _ => self.temp_c(t_s),
        }
    }

    /// Temperature at the start of the run, deg C.
    pub fn start_c(&self) -> f64 {
        self.temp_c(0.0)
    }
}

/// Piecewise-linear interpolation through `points`, held outside them. At a time shared by
/// two points (a step) the later point's value applies (right-continuous), or the earlier
/// one's with `left_limit`.
fn piecewise(points: &[[f64; 2]], t_s: f64, left_limit: bool) -> f64 {
    let Some(first) = points.first() else { return f64::NAN };
    if t_s <= first[0] {
        return first[1];
    }
    for w in points.windows(2) {
        let ([t0, v0], [t1, v1]) = (w[0], w[1]);
        if t_s < t1 || (left_limit && t_s == t1) {
            return if t1 > t0 { v0 + (v1 - v0) * (t_s - t0) / (t1 - t0) } else { v1 };
        }
    }
    points.last().map_or(f64::NAN, |p| p[1])
}

/// The gyro's input axis, in the local north-east-down frame.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum InputAxis {
    /// A named direction.
    Named(Direction),
    /// A vector `[north, east, down]` (normalised on use).
    Ned([f64; 3]),
}

/// Named input-axis directions.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Direction {
    /// Pointing up (away from the Earth's centre).
    Up,
    /// Pointing down.
    Down,
    /// Level, north.
    North,
    /// Level, south.
    South,
    /// Level, east.
    East,
    /// Level, west.
    West,
}

impl InputAxis {
    /// Unit vector `[north, east, down]`; `None` for a zero or non-finite vector.
    pub fn ned(&self) -> Option<[f64; 3]> {
        let v = match self {
            Self::Named(Direction::Up) => [0.0, 0.0, -1.0],
            Self::Named(Direction::Down) => [0.0, 0.0, 1.0],
            Self::Named(Direction::North) => [1.0, 0.0, 0.0],
            Self::Named(Direction::South) => [-1.0, 0.0, 0.0],
            Self::Named(Direction::East) => [0.0, 1.0, 0.0],
            Self::Named(Direction::West) => [0.0, -1.0, 0.0],
            Self::Ned(v) => *v,
        };
        let norm = v.iter().map(|x| x * x).sum::<f64>().sqrt();
        (norm.is_finite() && norm > 0.0).then(|| v.map(|x| x / norm))
    }

    /// Earth rate on this axis, deg/h: Omega (cos(lat) u_N - sin(lat) u_D) (docs/physics.md section 1).
    pub fn earth_rate_dph(&self, site: &Site) -> f64 {
        let Some([n, _, d]) = self.ned() else { return f64::NAN };
        let lat = site.latitude_deg.to_radians();
        site.earth_rate_dph * (lat.cos() * n - lat.sin() * d)
    }
}

/// How the unit starts the run.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum InitialState {
    /// Soaked unpowered at the chamber's start temperature, powered on at t = 0 (the paper).
    #[default]
    Soaked,
    /// Hot restart: already at its powered steady state at the chamber's start temperature.
    Warm,
}

/// One run (one power-on, one log file).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RunSpec {
    /// File stem of the log.
    pub name: String,
    /// Position / orientation label (e.g. `pos1`).
    #[serde(default)]
    pub group: String,
    /// Length, s.
    pub duration_s: f64,
    /// Chamber set temperature over the run.
    pub chamber: ChamberProfile,
    /// The gyro's input axis.
    pub input_axis: InputAxis,
    /// Soaked (power-on) or warm (hot restart).
    #[serde(default)]
    pub initial: InitialState,
}

/// Every start temperature at every position, at a constant chamber temperature.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RunGrid {
    /// Chamber temperatures, deg C.
    pub start_temps_c: Vec<f64>,
    /// Length of each run, s.
    pub duration_s: f64,
    /// The positions, in order.
    pub positions: Vec<Position>,
}

/// A named orientation of the unit.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Position {
    /// Label, used in run names (`pos1_-40C`).
    pub group: String,
    /// Input axis.
    pub input_axis: InputAxis,
}

impl Scenario {
    /// The built-in scenario of the paper's experiment.
    ///
    /// # Errors
    /// Never in a released build (the file is checked by the tests).
    pub fn paper() -> Result<Self, SimError> {
        Self::from_toml(PAPER_TOML, "built-in paper scenario")
    }

    /// Parses and validates a scenario; `origin` names the text in errors.
    ///
    /// # Errors
    /// [`SimError::Scenario`] with the TOML parser's line and column, or the invalid field.
    pub fn from_toml(text: &str, origin: &str) -> Result<Self, SimError> {
        let scenario: Self = toml::from_str(text).map_err(|e| {
            let (line, column) = e.span().map_or((None, None), |span| line_column(text, span.start));
            SimError::Scenario { origin: origin.to_string(), line, column, message: e.to_string() }
        })?;
        scenario.validate().map_err(|message| SimError::Scenario {
            origin: origin.to_string(),
            line: None,
            column: None,
            message,
        })?;
        Ok(scenario)
    }

    /// The scenario as TOML (without the comments of the built-in file).
    ///
    /// # Errors
    /// [`SimError::Serialise`] if serialisation fails.
    pub fn to_toml(&self) -> Result<String, SimError> {
        toml::to_string_pretty(self)
            .map_err(|e| SimError::Serialise { what: "scenario", message: e.to_string() })
    }

    /// Grid runs first (position-major, then start temperature), then the explicit runs.
    pub fn expanded_runs(&self) -> Vec<RunSpec> {
        let mut runs = Vec::new();
        if let Some(grid) = &self.grid {
            for position in &grid.positions {
                for &temp_c in &grid.start_temps_c {
                    runs.push(RunSpec {
                        name: format!("{}_{}C", position.group, format_temp(temp_c)),
                        group: position.group.clone(),
                        duration_s: grid.duration_s,
                        chamber: ChamberProfile::Constant { temp_c },
                        input_axis: position.input_axis.clone(),
                        initial: InitialState::Soaked,
                    });
                }
            }
        }
        runs.extend(self.runs.iter().cloned());
        runs
    }

    /// Applies the command line's overrides (`simulate --rate --seed --duration-s`, the same
    /// keywords in Python): the sample rate, the seed, and every run's duration (and the grid's),
    /// then validates. Returns whether anything was overridden.
    ///
    /// # Errors
    /// As [`Scenario::validate`], for the scenario after the overrides.
    pub fn apply_overrides(
        &mut self,
        rate_hz: Option<f64>,
        seed: Option<u64>,
        duration_s: Option<f64>,
    ) -> Result<bool, String> {
        if let Some(rate) = rate_hz {
            self.sample_rate_hz = rate;
        }
        if let Some(seed) = seed {
            self.seed = seed;
        }
        if let Some(duration) = duration_s {
            if let Some(grid) = &mut self.grid {
                grid.duration_s = duration;
            }
            for run in &mut self.runs {
                run.duration_s = duration;
            }
        }
        let overridden = rate_hz.is_some() || seed.is_some() || duration_s.is_some();
        if overridden {
            self.validate()?;
        }
        Ok(overridden)
    }

    /// The comment line `simulate` writes above a scenario it stores after overrides: what
    /// was overridden, in words (`# paper with overrides: rate 1 Hz, seed 3`).
    pub fn overrides_comment(
        name: &str,
        rate_hz: Option<f64>,
        seed: Option<u64>,
        duration_s: Option<f64>,
    ) -> String {
        let mut parts = Vec::new();
        if let Some(rate) = rate_hz {
            parts.push(format!("rate {rate} Hz"));
        }
        if let Some(seed) = seed {
            parts.push(format!("seed {seed}"));
        }
        if let Some(duration) = duration_s {
            parts.push(format!("every run {duration} s long"));
        }
        format!("# {name} with overrides: {}", parts.join(", "))
    }

    /// Checks every number that the simulator relies on.
    ///
    /// # Errors
    /// A message naming the field.
    pub fn validate(&self) -> Result<(), String> {
        let positive = [
            ("sample_rate_hz", self.sample_rate_hz),
            ("thermal.electronics_heat_capacity_j_per_k", self.thermal.electronics_heat_capacity_j_per_k),
            ("thermal.case_heat_capacity_j_per_k", self.thermal.case_heat_capacity_j_per_k),
            ("thermal.coil_outer_heat_capacity_j_per_k", self.thermal.coil_outer_heat_capacity_j_per_k),
            ("thermal.coil_inner_heat_capacity_j_per_k", self.thermal.coil_inner_heat_capacity_j_per_k),
            ("thermal.step_s", self.thermal.step_s),
            ("sensor.time_constant_s", self.sensor.time_constant_s),
            ("sensor.rate_hz", self.sensor.rate_hz),
            ("bias.warmup_time_constant_s", self.bias.warmup_time_constant_s),
            ("bias.hysteresis_rate_c_per_min", self.bias.hysteresis_rate_c_per_min),
            ("bias.static_ripple_period_c", self.bias.static_ripple_period_c),
            ("bias.cycling_period_s", self.bias.cycling_period_s),
            ("noise.flicker_tau_min_s", self.noise.flicker_tau_min_s),
            ("noise.flicker_tau_max_s", self.noise.flicker_tau_max_s),
        ];
        for (name, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return Err(format!("{name} must be a positive number (found {v})"));
            }
        }
        let non_negative = [
            ("thermal.electronics_case_w_per_k", self.thermal.electronics_case_w_per_k),
            ("thermal.case_coil_w_per_k", self.thermal.case_coil_w_per_k),
            ("thermal.coil_radial_w_per_k", self.thermal.coil_radial_w_per_k),
            ("thermal.case_ambient_w_per_k", self.thermal.case_ambient_w_per_k),
            ("thermal.power_w", self.thermal.power_w),
            ("thermal.tec_w_per_k", self.thermal.tec_w_per_k),
            ("thermal.heater_w", self.thermal.heater_w),
            ("sensor.noise_c", self.sensor.noise_c),
            ("sensor.quantum_c", self.sensor.quantum_c),
            ("bias.turn_on_sigma_dph", self.bias.turn_on_sigma_dph),
            ("noise.arw_deg_per_sqrt_h", self.noise.arw_deg_per_sqrt_h),
            ("noise.bias_instability_dph", self.noise.bias_instability_dph),
            ("noise.rrw_dph_per_sqrt_h", self.noise.rrw_dph_per_sqrt_h),
            ("noise.angle_lsb_arcsec", self.noise.angle_lsb_arcsec),
            ("chamber.ripple_amplitude_c", self.chamber.ripple_amplitude_c),
            ("chamber.ripple_period_s", self.chamber.ripple_period_s),
        ];
        for (name, v) in non_negative {
            if !(v.is_finite() && v >= 0.0) {
                return Err(format!("{name} must be a non-negative number (found {v})"));
            }
        }
        let finite = [
            ("site.latitude_deg", self.site.latitude_deg),
            ("site.earth_rate_dph", self.site.earth_rate_dph),
            ("thermal.tec_setpoint_c", self.thermal.tec_setpoint_c),
            ("thermal.heater_below_c", self.thermal.heater_below_c),
            ("sensor.offset_c", self.sensor.offset_c),
            ("bias.reference_temp_c", self.bias.reference_temp_c),
            ("bias.shupe_dph_per_c_per_min", self.bias.shupe_dph_per_c_per_min),
            ("bias.gradient_dph_per_c", self.bias.gradient_dph_per_c),
            ("bias.gradient_rate_dph_per_c_per_min", self.bias.gradient_rate_dph_per_c_per_min),
            ("bias.warmup_amplitude_dph", self.bias.warmup_amplitude_dph),
            ("bias.hysteresis_dph", self.bias.hysteresis_dph),
            ("bias.static_ripple_dph", self.bias.static_ripple_dph),
            ("bias.scale_factor_ppm", self.bias.scale_factor_ppm),
            ("bias.scale_factor_ppm_per_c", self.bias.scale_factor_ppm_per_c),
            ("bias.cycling_dph", self.bias.cycling_dph),
        ];
        for (name, v) in finite {
            if !v.is_finite() {
                return Err(format!("{name} must be a finite number (found {v})"));
            }
        }
        if let Some(i) = self.bias.static_dph.iter().position(|c| !c.is_finite()) {
            return Err(format!("bias.static_dph[{i}] must be finite"));
        }
        if self.site.latitude_deg.abs() > 90.0 {
            return Err(format!("site.latitude_deg must be within +-90 (found {})", self.site.latitude_deg));
        }
        if self.thermal.case_ambient_w_per_k <= 0.0 {
            return Err("thermal.case_ambient_w_per_k must be positive (the unit must exchange heat with the chamber)"
                .into());
        }
        if self.chamber.ripple_amplitude_c > 0.0 && self.chamber.ripple_period_s <= 0.0 {
            return Err("chamber.ripple_period_s must be positive when there is a ripple".into());
        }
        if self.sensor.mount == Node::Sensor {
            return Err("sensor.mount must be electronics, case or coil".into());
        }
        if self.noise.flicker_tau_max_s < self.noise.flicker_tau_min_s {
            return Err("noise.flicker_tau_max_s must not be below noise.flicker_tau_min_s".into());
        }
        let runs = self.expanded_runs();
        if runs.is_empty() {
            return Err("no runs: give a [grid] or [[runs]]".into());
        }
        let mut names = std::collections::HashSet::new();
        for run in &runs {
            validate_run(run)?;
            if !names.insert(run.name.clone()) {
                return Err(format!("two runs are named '{}'", run.name));
            }
        }
        Ok(())
    }
}

/// 1-based line and column of byte `offset` in `text`.
fn line_column(text: &str, offset: usize) -> (Option<usize>, Option<usize>) {
    let before = text.get(..offset).unwrap_or(text);
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (Some(line), Some(column))
}

fn validate_run(run: &RunSpec) -> Result<(), String> {
    let name = &run.name;
    if name.is_empty() || name.contains(['/', '\\']) || name.starts_with('.') {
        return Err(format!("run name '{name}' must be a plain file stem"));
    }
    if !(run.duration_s.is_finite() && run.duration_s > 0.0 && run.duration_s <= 30.0 * 86_400.0) {
        return Err(format!("run '{name}': duration_s must be in (0, 30 days] (found {})", run.duration_s));
    }
    if run.input_axis.ned().is_none() {
        return Err(format!("run '{name}': input_axis must be a non-zero finite vector"));
    }
    let profile_ok = match &run.chamber {
        ChamberProfile::Constant { temp_c } => temp_c.is_finite(),
        ChamberProfile::Ramp { start_c, end_c, rate_c_per_min, start_s } => {
            [start_c, end_c, start_s].iter().all(|v| v.is_finite())
                && rate_c_per_min.is_finite()
                && *rate_c_per_min != 0.0
        }
        ChamberProfile::Step { start_c, to_c, at_s } => [start_c, to_c, at_s].iter().all(|v| v.is_finite()),
        ChamberProfile::Sinusoid { mean_c, amplitude_c, period_s } => {
            mean_c.is_finite() && amplitude_c.is_finite() && period_s.is_finite() && *period_s > 0.0
        }
        ChamberProfile::Points { points } => {
            !points.is_empty()
                && points.iter().flatten().all(|v| v.is_finite())
                && points.windows(2).all(|w| w[1][0] >= w[0][0])
        }
    };
    if !profile_ok {
        return Err(format!(
            "run '{name}': chamber profile has a non-finite value, a zero ramp rate, a non-positive period \
             or points out of time order"
        ));
    }
    Ok(())
}

/// `-40` -> `-40`, `5` -> `5`, `2.5` -> `2.5`.
fn format_temp(temp_c: f64) -> String {
    if temp_c.fract() == 0.0 {
        format!("{temp_c:.0}")
    } else {
        format!("{temp_c}")
    }
}
