//! The lumped thermal network and its exact discrete step (docs/physics.md section 2).
//!
//! State `[T_e, T_c, T_o, T_i, T_s]` (electronics, case, coil outer, coil inner, sensor),
//! inputs `[P, T_a]` (power, chamber air). Between steps the power is held and the chamber
//! temperature moves linearly, and for such inputs `x(t+h) = Phi x + Gamma0 u + Gamma1 du/dt`
//! is exact: `Phi`, `Gamma0`, `Gamma1` are blocks of the exponential of the augmented matrix
//! `[[A, B, 0], [0, 0, I], [0, 0, 0]] h` (Van Loan), so no stability limit applies to `h`.

use nalgebra::{SMatrix, SVector};

use super::scenario::{Node, SensorParams, ThermalParams};

/// Number of thermal states.
pub const STATES: usize = 5;
/// Index of the electronics node.
pub const ELECTRONICS: usize = 0;
/// Index of the case node.
pub const CASE: usize = 1;
/// Index of the coil's outer layer.
pub const COIL_OUTER: usize = 2;
/// Index of the coil's inner layer.
pub const COIL_INNER: usize = 3;
/// Index of the sensor's own temperature.
pub const SENSOR: usize = 4;

/// Node temperatures, deg C.
pub type State = SVector<f64, STATES>;

const AUG: usize = STATES + 4;

/// The network with its precomputed discrete step.
#[derive(Clone, Debug)]
pub struct ThermalModel {
    a: SMatrix<f64, STATES, STATES>,
    b: SMatrix<f64, STATES, 2>,
    phi: SMatrix<f64, STATES, STATES>,
    gamma0: SMatrix<f64, STATES, 2>,
    gamma1: SMatrix<f64, STATES, 2>,
    step_s: f64,
    params: ThermalParams,
}

impl ThermalModel {
    /// Builds `A`, `B` and the exact step of length `params.step_s`. The sensor sits on
    /// `sensor.mount` (`Sensor` means the case).
    pub fn new(params: &ThermalParams, sensor: &SensorParams) -> Self {
        let p = params;
        let mut a = SMatrix::<f64, STATES, STATES>::zeros();
        let mut b = SMatrix::<f64, STATES, 2>::zeros();
        let (ce, cc, co, ci) = (
            p.electronics_heat_capacity_j_per_k,
            p.case_heat_capacity_j_per_k,
            p.coil_outer_heat_capacity_j_per_k,
            p.coil_inner_heat_capacity_j_per_k,
        );
        let (gec, gco, goi, gca) =
            (p.electronics_case_w_per_k, p.case_coil_w_per_k, p.coil_radial_w_per_k, p.case_ambient_w_per_k);
        // C_e dT_e = P - G_ec (T_e - T_c)
        a[(ELECTRONICS, ELECTRONICS)] = -gec / ce;
        a[(ELECTRONICS, CASE)] = gec / ce;
        b[(ELECTRONICS, 0)] = 1.0 / ce;
        // C_c dT_c = G_ec (T_e - T_c) - G_co (T_c - T_o) - G_ca (T_c - T_a)
        a[(CASE, ELECTRONICS)] = gec / cc;
        a[(CASE, CASE)] = -(gec + gco + gca) / cc;
        a[(CASE, COIL_OUTER)] = gco / cc;
        b[(CASE, 1)] = gca / cc;
        // C_o dT_o = G_co (T_c - T_o) - G_oi (T_o - T_i)
        a[(COIL_OUTER, CASE)] = gco / co;
        a[(COIL_OUTER, COIL_OUTER)] = -(gco + goi) / co;
        a[(COIL_OUTER, COIL_INNER)] = goi / co;
        // C_i dT_i = G_oi (T_o - T_i)
        a[(COIL_INNER, COIL_OUTER)] = goi / ci;
        a[(COIL_INNER, COIL_INNER)] = -goi / ci;
        // tau_s dT_s = T_mount - T_s
        let k = 1.0 / sensor.time_constant_s;
        match sensor.mount {
            Node::Electronics => a[(SENSOR, ELECTRONICS)] = k,
            Node::Case | Node::Sensor => a[(SENSOR, CASE)] = k,
            Node::Coil => {
                a[(SENSOR, COIL_OUTER)] = 0.5 * k;
                a[(SENSOR, COIL_INNER)] = 0.5 * k;
            }
        }
        a[(SENSOR, SENSOR)] = -k;

        let h = params.step_s;
        let mut m = SMatrix::<f64, AUG, AUG>::zeros();
        m.fixed_view_mut::<STATES, STATES>(0, 0).copy_from(&(a * h));
        m.fixed_view_mut::<STATES, 2>(0, STATES).copy_from(&(b * h));
        m.fixed_view_mut::<2, 2>(STATES, STATES + 2).copy_from(&(SMatrix::<f64, 2, 2>::identity() * h));
        let e = m.exp();
        let phi = e.fixed_view::<STATES, STATES>(0, 0).into_owned();
        let gamma0 = e.fixed_view::<STATES, 2>(0, STATES).into_owned();
        let gamma1 = e.fixed_view::<STATES, 2>(0, STATES + 2).into_owned();
        Self { a, b, phi, gamma0, gamma1, step_s: h, params: params.clone() }
    }

    /// The step length, s.
    pub fn step_s(&self) -> f64 {
        self.step_s
    }

    /// Power dissipated after power-on at state `x`, W.
    pub fn power_w(&self, x: &State) -> f64 {
        let p = &self.params;
        let t_e = x[ELECTRONICS];
        let heater = if t_e < p.heater_below_c { p.heater_w } else { 0.0 };
        p.power_w + p.tec_w_per_k * (t_e - p.tec_setpoint_c).abs() + heater
    }

    /// dx/dt, deg C/s.
    pub fn derivative(&self, x: &State, power_w: f64, ambient_c: f64) -> State {
        self.a * x + self.b * SVector::<f64, 2>::new(power_w, ambient_c)
    }

    /// One exact step: power held at `power_w`, chamber from `ambient_c` to `ambient_next_c`.
    pub fn step(&self, x: &State, power_w: f64, ambient_c: f64, ambient_next_c: f64) -> State {
        let u = SVector::<f64, 2>::new(power_w, ambient_c);
        let du = SVector::<f64, 2>::new(0.0, (ambient_next_c - ambient_c) / self.step_s);
        self.phi * x + self.gamma0 * u + self.gamma1 * du
    }

    /// Every node at `temp_c` (soaked, unpowered).
    pub fn soaked(temp_c: f64) -> State {
        State::from_element(temp_c)
    }

    /// The powered steady state in a chamber at `ambient_c` (fixed point over the power law).
    pub fn warm(&self, ambient_c: f64) -> State {
        let mut x = Self::soaked(ambient_c);
        let Some(a_inv) = self.a.try_inverse() else { return x };
        for _ in 0..100 {
            let u = SVector::<f64, 2>::new(self.power_w(&x), ambient_c);
            let next = -(a_inv * (self.b * u));
            let change = (next - x).amax();
            x = next;
            if change < 1e-12 {
                break;
            }
        }
        x
    }
}

/// Temperature of `node` in state `x`, deg C (`Coil` is the mean of its two layers).
pub fn node_temp_c(x: &State, node: Node) -> f64 {
    match node {
        Node::Electronics => x[ELECTRONICS],
        Node::Case => x[CASE],
        Node::Coil => 0.5 * (x[COIL_OUTER] + x[COIL_INNER]),
        Node::Sensor => x[SENSOR],
    }
}
