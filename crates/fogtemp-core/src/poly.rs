//! Polynomial bias model in the normalised inputs: `sum_k c_k * x^i_k * y^j_k`.

use crate::wire::{self, MAX_POWER, POLY_TERM_LEN};

/// One polynomial term `coefficient_dph * x^temp_power * y^rate_power` (normalised inputs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PolyTerm {
    /// Power of the normalised temperature `x`.
    pub temp_power: u8,
    /// Power of the normalised rate `y`.
    pub rate_power: u8,
    /// Coefficient in deg/h.
    pub coefficient_dph: f32,
}

/// The polynomial part of an axis, borrowed from the blob (validated by `Model::from_bytes`).
#[derive(Clone, Copy, Debug)]
pub struct Poly<'a> {
    terms: &'a [u8],
}

impl<'a> Poly<'a> {
    pub(crate) fn new(terms: &'a [u8]) -> Self {
        Self { terms }
    }

    /// Number of terms.
    pub fn len(&self) -> usize {
        self.terms.len() / POLY_TERM_LEN
    }

    /// True when the polynomial has no terms.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The terms, in blob order.
    pub fn terms(&self) -> impl Iterator<Item = PolyTerm> + 'a {
        self.terms.chunks_exact(POLY_TERM_LEN).map(parse_term)
    }

    pub(crate) fn raw_terms(&self) -> core::slice::ChunksExact<'a, u8> {
        self.terms.chunks_exact(POLY_TERM_LEN)
    }

    /// Value in deg/h at normalised inputs `(x, y)`.
    ///
    /// Powers come from a table built by repeated multiplication (no `powf`), so the
    /// result is exact to f32 rounding of each product; with `|x|, |y| <= 1` the
    /// relative error is below `(2 * MAX_POWER + 1) * f32::EPSILON` per term.
    pub fn evaluate(&self, x: f32, y: f32) -> f32 {
        let xp = powers(x);
        let yp = powers(y);
        self.terms().fold(0.0, |sum, t| {
            let xi = xp.get(usize::from(t.temp_power)).copied().unwrap_or(0.0);
            let yj = yp.get(usize::from(t.rate_power)).copied().unwrap_or(0.0);
            sum + t.coefficient_dph * xi * yj
        })
    }
}

impl Poly<'_> {
    /// Value and gradient `(p, dp/dx, dp/dy)` in deg/h (per normalised unit) at `(x, y)`,
    /// from the same power tables as [`Poly::evaluate`] (the value is bit-identical to it).
    pub fn evaluate_with_gradient(&self, x: f32, y: f32) -> (f32, f32, f32) {
        let xp = powers(x);
        let yp = powers(y);
        let power =
            |table: &[f32; MAX_POWER as usize + 1], k: u8| table.get(usize::from(k)).copied().unwrap_or(0.0);
        self.terms().fold((0.0, 0.0, 0.0), |(sum, d_dx, d_dy), t| {
            let (i, j) = (t.temp_power, t.rate_power);
            let (xi, yj) = (power(&xp, i), power(&yp, j));
            // d/dx x^i = i x^(i-1); a power of 0 contributes nothing.
            let dxi = if i > 0 { f32::from(i) * power(&xp, i - 1) } else { 0.0 };
            let dyj = if j > 0 { f32::from(j) * power(&yp, j - 1) } else { 0.0 };
            (
                sum + t.coefficient_dph * xi * yj,
                d_dx + t.coefficient_dph * dxi * yj,
                d_dy + t.coefficient_dph * xi * dyj,
            )
        })
    }
}

/// `[1, v, v^2, ..., v^MAX_POWER]`.
fn powers(v: f32) -> [f32; MAX_POWER as usize + 1] {
    let mut p = [1.0f32; MAX_POWER as usize + 1];
    let mut acc = 1.0f32;
    for slot in p.iter_mut().skip(1) {
        acc *= v;
        *slot = acc;
    }
    p
}

#[inline]
pub(crate) fn parse_term(chunk: &[u8]) -> PolyTerm {
    PolyTerm {
        temp_power: chunk.first().copied().unwrap_or(0),
        rate_power: chunk.get(1).copied().unwrap_or(0),
        coefficient_dph: wire::f32_at(chunk, 4).unwrap_or(0.0),
    }
}
