//! Gyro noise (docs/physics.md section 3): angle random walk (white rate), bias instability as a
//! sum of first-order Gauss-Markov terms (one per decade of correlation time), rate random
//! walk. Quantisation of the output angle is applied by the run generator.

use rand::Rng;
use rand_distr::StandardNormal;

use super::scenario::NoiseParams;

/// One first-order Gauss-Markov term, updated every `every` samples with the exact
/// discretisation `x <- phi x + sqrt(q (1 - phi^2)) w` and held in between.
#[derive(Clone, Debug)]
struct GaussMarkov {
    phi: f64,
    drive: f64,
    every: u64,
    countdown: u64,
    x: f64,
}

/// The random part of the gyro output, one sample at a time, deg/h.
#[derive(Clone, Debug)]
pub struct NoiseGenerator {
    white_sigma_dph: f64,
    terms: Vec<GaussMarkov>,
    rrw_sigma_dph: f64,
    rrw_every: u64,
    rrw_countdown: u64,
    rrw_dph: f64,
}

/// The stationary variance of each decade's Gauss-Markov term for bias instability `b_dph`:
/// `q = B^2 ln(10) / pi` (docs/physics.md section 3; its Allan deviation is flat at about 0.66-0.69 B).
pub fn flicker_term_variance(b_dph: f64) -> f64 {
    b_dph * b_dph * std::f64::consts::LN_10 / std::f64::consts::PI
}

/// Per-sample standard deviation of white rate noise for ARW `n_deg_per_sqrt_h` at
/// `rate_hz`: `60 N sqrt(f_s)` deg/h.
pub fn white_sigma_dph(n_deg_per_sqrt_h: f64, rate_hz: f64) -> f64 {
    60.0 * n_deg_per_sqrt_h * rate_hz.sqrt()
}

impl NoiseGenerator {
    /// A generator at `rate_hz`; slow terms start in their stationary distribution.
    pub fn new(params: &NoiseParams, rate_hz: f64, rng: &mut impl Rng) -> Self {
        let dt_s = 1.0 / rate_hz;
        let q = flicker_term_variance(params.bias_instability_dph);
        let mut terms = Vec::new();
        if q > 0.0 {
            let mut tau_s = params.flicker_tau_min_s;
            while tau_s <= params.flicker_tau_max_s * (1.0 + 1e-9) {
                // Update ten times per correlation time (at most once a second, at least
                // every sample): the held value then differs from a per-sample update only
                // far above the term's corner frequency, where white noise dominates.
                let every = ((tau_s / 10.0).min(1.0) / dt_s).round().max(1.0) as u64;
                let phi = (-(every as f64) * dt_s / tau_s).exp();
                let x = q.sqrt() * rng.sample::<f64, _>(StandardNormal);
                terms.push(GaussMarkov {
                    phi,
                    drive: (q * (1.0 - phi * phi)).sqrt(),
                    every,
                    countdown: every,
                    x,
                });
                tau_s *= 10.0;
            }
        }
        let rrw_every = (0.1 / dt_s).round().max(1.0) as u64;
        let rrw_dt_h = rrw_every as f64 * dt_s / 3600.0;
        Self {
            white_sigma_dph: white_sigma_dph(params.arw_deg_per_sqrt_h, rate_hz),
            terms,
            rrw_sigma_dph: params.rrw_dph_per_sqrt_h * rrw_dt_h.sqrt(),
            rrw_every,
            rrw_countdown: rrw_every,
            rrw_dph: 0.0,
        }
    }

    /// The next sample's noise, deg/h.
    pub fn next(&mut self, rng: &mut impl Rng) -> f64 {
        let mut sum = self.rrw_dph;
        for term in &mut self.terms {
            term.countdown -= 1;
            if term.countdown == 0 {
                term.countdown = term.every;
                term.x = term.phi * term.x + term.drive * rng.sample::<f64, _>(StandardNormal);
            }
            sum += term.x;
        }
        if self.rrw_sigma_dph > 0.0 {
            self.rrw_countdown -= 1;
            if self.rrw_countdown == 0 {
                self.rrw_countdown = self.rrw_every;
                self.rrw_dph += self.rrw_sigma_dph * rng.sample::<f64, _>(StandardNormal);
            }
        }
        if self.white_sigma_dph > 0.0 {
            sum += self.white_sigma_dph * rng.sample::<f64, _>(StandardNormal);
        }
        sum
    }
}
