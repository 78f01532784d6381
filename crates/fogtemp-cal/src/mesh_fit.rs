//! Least-squares node values: the mesh as a piecewise-linear regression on all calibration
//! points instead of an interpolant through a few noisy ones.
//!
//! The paper interpolates through thinned, smoothed points: every node value carries the
//! full noise of one smoothed target, and the interpolation hands that noise to the
//! compensated output. Here the node positions come from thinning, and the node values
//! `v` minimise `sum_p (sum_k w_pk v_k - y_p)^2 + ridge * sum_k (v_k - v0_k)^2`, where
//! `w_pk` are the barycentric weights of point `p` in the final mesh (exactly how the
//! firmware interpolates) and `v0` the nodes' own targets (the weak ridge only matters for
//! nodes with little data). Solved by CGLS on the sparse system (3 non-zeros per point),
//! so no normal matrix is formed.

use spade::{DelaunayTriangulation, FloatTriangulation, Point2, Triangulation};

use crate::error::CalError;
use crate::mesh::MeshModel;

/// What the node-value fit did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NodeFitReport {
    /// Points inside the mesh used in the fit.
    pub points_used: usize,
    /// Points outside the mesh hull (not used).
    pub points_outside: usize,
    /// CGLS iterations.
    pub iterations: usize,
    /// RMS of (interpolated - target) over the used points before the fit, deg/h.
    pub rms_before_dph: f64,
    /// The same after the fit, deg/h.
    pub rms_after_dph: f64,
}

/// Refits `mesh`'s vertex values to `points` (normalised `x`, `y` as f32 exactly as the
/// firmware computes them, and the target value). `ridge` is relative to the mean number
/// of points per node (1e-3 is a light touch).
///
/// # Errors
/// [`CalError::DegenerateMesh`] if the mesh vertices cannot be triangulated again.
pub fn fit_node_values(
    mesh: &mut MeshModel,
    points: &[(f32, f32, f64)],
    ridge: f64,
) -> Result<NodeFitReport, CalError> {
    let n = mesh.vertices.len();
    let mut dt: DelaunayTriangulation<Point2<f64>> = DelaunayTriangulation::new();
    for (index, v) in mesh.vertices.iter().enumerate() {
        let handle = dt
            .insert(Point2::new(f64::from(v.x), f64::from(v.y)))
            .map_err(|_| CalError::NonFinite { what: "mesh vertex", index })?;
        if handle.index() != index {
            return Err(CalError::DegenerateMesh { reason: "duplicate mesh vertex", points: n });
        }
    }
    // Sparse rows: up to three (vertex, weight) pairs per point.
    let interp = dt.barycentric();
    let mut rows: Vec<([usize; 3], [f64; 3], f64)> = Vec::with_capacity(points.len());
    let mut weights = Vec::new();
    let mut outside = 0;
    for &(x, y, value) in points {
        interp.get_weights(Point2::new(f64::from(x), f64::from(y)), &mut weights);
        if weights.is_empty() {
            outside += 1;
            continue;
        }
        let mut idx = [0usize; 3];
        let mut w = [0.0f64; 3];
        for (k, (h, wk)) in weights.iter().take(3).enumerate() {
            idx[k] = h.index();
            w[k] = *wk;
        }
        rows.push((idx, w, value));
    }
    let v0: Vec<f64> = mesh.vertices.iter().map(|v| f64::from(v.value_dph)).collect();
    let lambda = ridge * (rows.len() as f64 / n.max(1) as f64).max(1.0);
    let rms = |v: &[f64]| {
        let r: f64 = mul_rows(&rows, v).iter().zip(&rows).map(|(a, (_, _, y))| (a - y).powi(2)).sum();
        (r / rows.len().max(1) as f64).sqrt()
    };
    let rms_before_dph = rms(&v0);
    let (v, iterations) = cgls(&rows, &v0, lambda, n);
    let rms_after_dph = rms(&v);
    for (vertex, value) in mesh.vertices.iter_mut().zip(&v) {
        vertex.value_dph = *value as f32;
    }
    Ok(NodeFitReport {
        points_used: rows.len(),
        points_outside: outside,
        iterations,
        rms_before_dph,
        rms_after_dph,
    })
}

/// `A v` for the sparse rows (three weights each).
fn mul_rows(rows: &[([usize; 3], [f64; 3], f64)], v: &[f64]) -> Vec<f64> {
    rows.iter().map(|(i, w, _)| w[0] * v[i[0]] + w[1] * v[i[1]] + w[2] * v[i[2]]).collect()
}

/// CGLS for `min |A v - y|^2 + lambda |v - v0|^2`, solved for `d = v - v0` from `d = 0`.
fn cgls(rows: &[([usize; 3], [f64; 3], f64)], v0: &[f64], lambda: f64, n: usize) -> (Vec<f64>, usize) {
    let a_mul = |d: &[f64]| mul_rows(rows, d);
    let at_mul = |r: &[f64]| -> Vec<f64> {
        let mut out = vec![0.0; n];
        for ((i, w, _), rk) in rows.iter().zip(r) {
            for k in 0..3 {
                out[i[k]] += w[k] * rk;
            }
        }
        out
    };
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    // Residual of the data rows at d = 0, and of the ridge rows (zero).
    let mut d = vec![0.0; n];
    let av0 = a_mul(v0);
    let mut r: Vec<f64> = rows.iter().zip(&av0).map(|((_, _, y), a)| y - a).collect();
    let mut r_ridge = vec![0.0; n];
    let sqrt_l = lambda.sqrt();
    let grad = |r: &[f64], r_ridge: &[f64]| -> Vec<f64> {
        at_mul(r).iter().zip(r_ridge).map(|(g, rr)| g + sqrt_l * rr).collect()
    };
    let mut s = grad(&r, &r_ridge);
    let mut p = s.clone();
    let mut gamma = dot(&s, &s);
    let gamma0 = gamma;
    let max_iter = 4 * n + 100;
    for it in 0..max_iter {
        if gamma <= 1e-24 * gamma0.max(1e-300) {
            return (v0.iter().zip(&d).map(|(a, b)| a + b).collect(), it);
        }
        let q = a_mul(&p);
        let q_ridge: Vec<f64> = p.iter().map(|x| sqrt_l * x).collect();
        let alpha = gamma / (dot(&q, &q) + dot(&q_ridge, &q_ridge));
        for (dk, pk) in d.iter_mut().zip(&p) {
            *dk += alpha * pk;
        }
        for (rk, qk) in r.iter_mut().zip(&q) {
            *rk -= alpha * qk;
        }
        for (rk, qk) in r_ridge.iter_mut().zip(&q_ridge) {
            *rk -= alpha * qk;
        }
        s = grad(&r, &r_ridge);
        let gamma_new = dot(&s, &s);
        let beta = gamma_new / gamma;
        gamma = gamma_new;
        for (pk, sk) in p.iter_mut().zip(&s) {
            *pk = sk + beta * *pk;
        }
    }
    (v0.iter().zip(&d).map(|(a, b)| a + b).collect(), max_iter)
}
