//! Numbers as text for people: a deg/h figure to at most 5 decimals and 4 significant
//! figures.
//!
//! Five decimals keep the small figures fogtemp is about as before (0.01286, 0.00396: the
//! demo's Table 1, where four decimals printed poly and mesh alike). Above 0.1 they would
//! claim more than a bias stability from a few dozen windows holds: psim-tvc's "216.0326"
//! and "at most about 12.39106 deg/h" (review21 second report F7); 4 significant figures
//! give 216.0 and 12.39. A signed value that rounds to zero prints without a minus sign; an
//! unsigned figure below 5e-6 deg/h, which no FOG reaches, in scientific notation.

/// The decimals that show `v` to `significant` figures, at most `max_decimals` (and
/// `max_decimals` for 0 and non-finite values).
pub fn decimals_for(v: f64, max_decimals: usize, significant: usize) -> usize {
    if !v.is_finite() || v == 0.0 {
        return max_decimals;
    }
    let leading = v.abs().log10().floor();
    let wanted = significant as f64 - 1.0 - leading;
    if wanted <= 0.0 {
        0
    } else {
        (wanted as usize).min(max_decimals)
    }
}

/// Below this magnitude a nonzero deg/h figure prints in scientific notation, deg/h: five
/// decimals would print it as 0.00000, and no FOG is that quiet (a gyro logged in deg/s and
/// read as deg/h printed every figure as 0.00000 beside ratios of 1.02-1.86: review23b F4).
const SCIENTIFIC_BELOW_DPH: f64 = 5e-6;

/// A deg/h figure (bias stability, residual, floor): see the module documentation.
pub fn dph(v: f64) -> String {
    if v != 0.0 && v.abs() < SCIENTIFIC_BELOW_DPH {
        return format!("{v:.3e}");
    }
    let decimals = decimals_for(v, 5, 4);
    format!("{:.decimals$}", no_negative_zero(v, decimals))
}

/// [`dph`] with a sign always (`+0.00012`, `-216.0`).
pub fn dph_signed(v: f64) -> String {
    let decimals = decimals_for(v, 5, 4);
    format!("{:+.decimals$}", no_negative_zero(v, decimals))
}

/// `v`, or `+0.0` when it prints as zero at `decimals` (so `-0.000001` is not `-0.00000`).
fn no_negative_zero(v: f64, decimals: usize) -> f64 {
    let scale = 10f64.powi(decimals.min(300) as i32);
    if v.is_finite() && (v * scale).round() == 0.0 {
        0.0
    } else {
        v
    }
}

/// `- v` or, for a negative `v`, `+ |v|`, to `decimals` decimals: an offset taken away in a
/// formula (`dT/dt - -0.060096` read as a typo; review26b L7).
pub fn minus_text(v: f64, decimals: usize) -> String {
    if v < 0.0 {
        format!("+ {:.decimals$}", -v)
    } else {
        format!("- {v:.decimals$}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn small_figures_keep_five_decimals_and_large_ones_four_significant_figures() {
        assert_eq!(dph(0.012_857), "0.01286");
        assert_eq!(dph(0.003_962), "0.00396");
        assert_eq!(dph(0.000_012_3), "0.00001");
        assert_eq!(dph(0.512_34), "0.5123");
        assert_eq!(dph(216.0326), "216.0");
        assert_eq!(dph(14.2819), "14.28");
        assert_eq!(dph(12.391_06), "12.39");
        assert_eq!(dph(31_416.0), "31416");
        assert_eq!(dph(0.0), "0.00000");
        assert_eq!(dph(f64::NAN), "NaN");
    }

    #[test]
    fn a_figure_five_decimals_would_print_as_zero_is_in_scientific_notation() {
        assert_eq!(dph(1.65e-7), "1.650e-7");
        assert_eq!(dph(-0.000_001), "-1.000e-6");
        assert_eq!(dph(0.000_005), "0.00001");
    }

    #[test]
    fn a_value_that_rounds_to_zero_has_no_minus_sign() {
        assert_eq!(dph_signed(-0.000_001), "+0.00000");
        assert_eq!(dph_signed(-0.000_12), "-0.00012");
        assert_eq!(dph_signed(12.391), "+12.39");
    }
}
