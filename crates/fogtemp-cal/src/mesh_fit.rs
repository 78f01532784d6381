//! Node values of the mesh: a penalised least-squares fit to all calibration points, with
//! the smoothness weight chosen by cross-validation over runs.
//!
//! The paper interpolates through thinned, smoothed points: every node value carries the
//! full noise of one smoothed target, and the interpolation hands that noise to the
//! compensated output. Here the node positions come from thinning, and the node values `v`
//! minimise
//!
//! ```text
//! sum_p (sum_k w_pk v_k - y_p)^2  +  lambda * sum_e area_e |grad_t1(v) - grad_t2(v)|^2
//! ```
//!
//! where `w_pk` are the barycentric weights of point `p` in the final mesh (exactly how the
//! firmware interpolates), and the second sum runs over interior edges `e` of the
//! triangulation: the jump of the piecewise-linear surface's gradient between the two
//! triangles sharing the edge (a discrete second difference on the normalised axes), weighted
//! by a third of their combined area. Its null space is the planes, so a very large `lambda`
//! gives the least-squares plane in (T, dT/dt); a small one the unregularised fit.
//!
//! `lambda` is chosen from a log-spaced grid by leave-one-run-out cross-validation
//! ([`CalibrationPoints::run_of`](crate::calibrate::CalibrationPoints)), with the
//! one-standard-error rule toward the smoother model. For a hybrid's residual mesh the
//! candidates also include "no mesh" (all node values zero), the simplest of all: the hybrid
//! keeps its mesh only when held-out runs say it helps. The held-out error of a run is taken
//! about its own mean, as the validation's bias stability ignores a run's constant offset.

use nalgebra::{DMatrix, DVector};

use crate::error::CalError;
use crate::mesh::MeshModel;

/// Smoothness weights tried, relative to the balance `trace(A'A) / trace(R'R)` of the data
/// and penalty terms: 1e-4 (nearly unregularised) to 1e8 (the least-squares plane).
pub const RELATIVE_WEIGHTS: [f64; 13] = [1e-4, 1e-3, 1e-2, 1e-1, 1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8];

/// Fewest groups for cross-validation; with fewer runs each run is cut into contiguous
/// pieces to reach it.
pub const MIN_FOLDS: usize = 5;

/// What the node-value fit did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NodeFitReport {
    /// Points inside the mesh used in the fit.
    pub points_used: usize,
    /// Points outside the mesh hull (not used).
    pub points_outside: usize,
    /// RMS of (interpolated - target) over the used points before the fit, deg/h.
    pub rms_before_dph: f64,
    /// The same after the fit, deg/h.
    pub rms_after_dph: f64,
}

/// One candidate of the cross-validation.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct CvCandidate {
    /// Smoothness weight relative to the data/penalty balance; `None` for "no mesh".
    pub relative_weight: Option<f64>,
    /// Cross-validated RMS error (each held-out run about its own mean, mean over runs), deg/h.
    pub cv_rms_dph: f64,
    /// Standard error of the mean squared error over the held-out groups, expressed as the
    /// RMS at one standard error above the mean minus `cv_rms_dph`, deg/h.
    pub cv_se_dph: f64,
}

/// How the mesh's smoothness weight was chosen (`fit --json`: `axes[].mesh_smoothing`).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct MeshSmoothing {
    /// The chosen relative weight (`None`: no mesh).
    pub relative_weight: Option<f64>,
    /// The chosen absolute weight `lambda` (`None`: no mesh).
    pub weight: Option<f64>,
    /// "no mesh" was a candidate (hybrid residual meshes).
    pub no_mesh_allowed: bool,
    /// Held-out groups: "runs" (leave one run out) or "run pieces" (fewer than
    /// [`MIN_FOLDS`] runs, each cut into contiguous pieces).
    pub folds: &'static str,
    /// Number of held-out groups.
    pub fold_count: usize,
    /// Every candidate, simplest first ("no mesh", then the largest weight down).
    pub curve: Vec<CvCandidate>,
    /// RMS of (mesh - target) over the calibration points before and after the fit, deg/h.
    pub rms_before_dph: f64,
    /// See `rms_before_dph`.
    pub rms_after_dph: f64,
}

impl MeshSmoothing {
    /// Cross-validation chose no mesh.
    pub fn no_mesh(&self) -> bool {
        self.relative_weight.is_none()
    }
}

/// One point's row of the design matrix: three (vertex, barycentric weight) pairs.
#[derive(Clone, Copy, Debug)]
struct Row {
    vertex: [usize; 3],
    weight: [f64; 3],
    value: f64,
    group: usize,
}

/// Fits `mesh`'s vertex values to `points` (normalised `x`, `y` as f32 exactly as the firmware
/// computes them, and the target value; `run_of[i]` is point `i`'s run) with the smoothness
/// weight chosen by cross-validation (see the module docs). With `allow_no_mesh`, "no mesh" is
/// a candidate; when it wins the vertex values are all set to zero and
/// [`MeshSmoothing::no_mesh`] is true (the caller drops the mesh).
///
/// # Errors
/// [`CalError::DegenerateMesh`] if a mesh triangle is degenerate or no point lies in the mesh.
pub fn fit_node_values_cv(
    mesh: &mut MeshModel,
    points: &[(f32, f32, f64)],
    run_of: &[usize],
    allow_no_mesh: bool,
) -> Result<(NodeFitReport, MeshSmoothing), CalError> {
    let n = mesh.vertices.len();
    let (mut rows, points_outside) = design_rows(mesh, points, run_of);
    if rows.is_empty() {
        return Err(CalError::DegenerateMesh { reason: "no calibration point lies in the mesh", points: n });
    }
    let (folds, fold_count) = assign_groups(&mut rows);
    let penalty = gradient_jump_penalty(mesh)?;
    let gram = normal_matrix(&rows, n, |_| true);
    let rhs = normal_rhs(&rows, n, |_| true);
    let balance = gram.trace() / penalty.trace().max(f64::MIN_POSITIVE);
    let ridge = 1e-10 * gram.trace() / n.max(1) as f64;
    let v0: Vec<f64> = mesh.vertices.iter().map(|v| f64::from(v.value_dph)).collect();
    let rms_before_dph = rms_misfit(&rows, &v0);

    let mut curve = Vec::new();
    if allow_no_mesh {
        let zero = vec![0.0; n];
        let errors: Vec<f64> = (0..fold_count).map(|g| held_out_mse(&rows, g, &zero)).collect();
        curve.push(candidate(None, &errors));
    }
    for &relative in RELATIVE_WEIGHTS.iter().rev() {
        let lambda = relative * balance;
        let errors: Vec<f64> = (0..fold_count)
            .map(|g| {
                let train = |r: &Row| r.group != g;
                let m = normal_matrix(&rows, n, train) + &penalty * lambda;
                solve(m, normal_rhs(&rows, n, train), ridge)
                    .map_or(f64::INFINITY, |v| held_out_mse(&rows, g, &v))
            })
            .collect();
        curve.push(candidate(Some(relative), &errors));
    }
    let chosen = one_standard_error(&curve);
    let relative_weight = curve.get(chosen).and_then(|c| c.relative_weight);
    let values = match relative_weight {
        Some(relative) => solve(gram + &penalty * (relative * balance), rhs, ridge)
            .ok_or(CalError::DegenerateMesh { reason: "mesh node fit is singular", points: n })?,
        None => vec![0.0; n],
    };
    let rms_after_dph = rms_misfit(&rows, &values);
    for (vertex, value) in mesh.vertices.iter_mut().zip(&values) {
        vertex.value_dph = *value as f32;
    }
    let report = NodeFitReport { points_used: rows.len(), points_outside, rms_before_dph, rms_after_dph };
    let smoothing = MeshSmoothing {
        relative_weight,
        weight: relative_weight.map(|r| r * balance),
        no_mesh_allowed: allow_no_mesh,
        folds,
        fold_count,
        curve,
        rms_before_dph,
        rms_after_dph,
    };
    Ok((report, smoothing))
}

/// Barycentric rows of every point inside the mesh (run index in `group` for now), and the
/// number of points outside it.
fn design_rows(mesh: &MeshModel, points: &[(f32, f32, f64)], run_of: &[usize]) -> (Vec<Row>, usize) {
    let transforms: Vec<Option<crate::blob::TriangleTransform>> =
        mesh.triangles.iter().map(|&tri| crate::blob::triangle_transform(mesh, tri)).collect();
    let mut rows = Vec::with_capacity(points.len());
    let (mut outside, mut hint) = (0, 0);
    for (i, &(x, y, value)) in points.iter().enumerate() {
        match locate(mesh, &transforms, x, y, &mut hint) {
            Some((vertex, weight)) => {
                rows.push(Row { vertex, weight, value, group: run_of.get(i).copied().unwrap_or(0) })
            }
            None => outside += 1,
        }
    }
    (rows, outside)
}

/// The triangle containing `(x, y)` (tried first: `hint`, the previous point's triangle, as
/// consecutive points are close; then a scan), tolerant of f32 rounding on edges, with the
/// point's barycentric weights on its vertices. Sets `hint` to the triangle found.
fn locate(
    mesh: &MeshModel,
    transforms: &[Option<crate::blob::TriangleTransform>],
    x: f32,
    y: f32,
    hint: &mut usize,
) -> Option<([usize; 3], [f64; 3])> {
    const EDGE_TOL: f64 = 1e-6;
    let bary = |t: usize| -> Option<([f64; 3], f64)> {
        let tf = transforms.get(t)?.as_ref()?;
        let (dx, dy) = (f64::from(x) - f64::from(tf.origin[0]), f64::from(y) - f64::from(tf.origin[1]));
        let l0 = tf.bary[0] * dx + tf.bary[1] * dy;
        let l1 = tf.bary[2] * dx + tf.bary[3] * dy;
        let l = [l0, l1, 1.0 - l0 - l1];
        Some((l, l.iter().copied().fold(f64::INFINITY, f64::min)))
    };
    let mut best: Option<(usize, [f64; 3], f64)> = None;
    for t in std::iter::once(*hint).chain(0..mesh.triangles.len()) {
        let Some((l, worst)) = bary(t) else { continue };
        if best.as_ref().is_none_or(|b| worst > b.2) {
            best = Some((t, l, worst));
        }
        if worst >= 0.0 {
            break;
        }
    }
    let (t, l, worst) = best?;
    if worst < -EDGE_TOL {
        return None;
    }
    *hint = t;
    // Clamp rounding on an edge back into the triangle.
    let clamped = l.map(|w| w.max(0.0));
    let sum: f64 = clamped.iter().sum();
    Some((mesh.triangles[t].map(|v| v as usize), clamped.map(|w| w / sum)))
}

/// Cross-validation groups: the runs when there are at least [`MIN_FOLDS`], otherwise each
/// run cut into contiguous pieces (points are in time order within a run) so that there are
/// about [`MIN_FOLDS`]. Rewrites `group` to 0..count and returns the kind and the count.
fn assign_groups(rows: &mut [Row]) -> (&'static str, usize) {
    let mut runs: Vec<usize> = rows.iter().map(|r| r.group).collect();
    runs.sort_unstable();
    runs.dedup();
    let index_of = |run: usize| runs.binary_search(&run).unwrap_or(0);
    if runs.len() >= MIN_FOLDS {
        for r in rows.iter_mut() {
            r.group = index_of(r.group);
        }
        return ("runs", runs.len());
    }
    let pieces = MIN_FOLDS.div_ceil(runs.len().max(1));
    let mut counts = vec![0usize; runs.len()];
    for r in rows.iter() {
        counts[index_of(r.group)] += 1;
    }
    let mut seen = vec![0usize; runs.len()];
    for r in rows.iter_mut() {
        let run = index_of(r.group);
        let piece = (seen[run] * pieces / counts[run].max(1)).min(pieces - 1);
        seen[run] += 1;
        r.group = run * pieces + piece;
    }
    ("run pieces", runs.len() * pieces)
}

/// `R'R` of the gradient-jump penalty (see the module docs).
fn gradient_jump_penalty(mesh: &MeshModel) -> Result<DMatrix<f64>, CalError> {
    let n = mesh.vertices.len();
    let degenerate = || CalError::DegenerateMesh { reason: "zero-area mesh triangle", points: n };
    // Per triangle: gradient coefficients of its three vertices, and its area.
    let mut grads: Vec<([usize; 3], [[f64; 2]; 3], f64)> = Vec::with_capacity(mesh.triangles.len());
    for &tri in &mesh.triangles {
        let tf = crate::blob::triangle_transform(mesh, tri).ok_or_else(degenerate)?;
        let [b0, b1, b2, b3] = tf.bary;
        let g = [[b0, b1], [b2, b3], [-(b0 + b2), -(b1 + b3)]];
        // |det| of the barycentric transform is 1 / (2 area).
        let det = (b0 * b3 - b1 * b2).abs();
        if det == 0.0 || !det.is_finite() {
            return Err(degenerate());
        }
        grads.push((tri.map(|v| v as usize), g, 0.5 / det));
    }
    let mut p = DMatrix::<f64>::zeros(n, n);
    for (t, neighbours) in mesh.neighbours.iter().enumerate() {
        for &nb in neighbours {
            let nb = nb as usize;
            if nb <= t || nb >= grads.len() {
                continue; // hull edge, or counted from the other side
            }
            let (ref vt, gt, at) = grads[t];
            let (ref vn, gn, an) = grads[nb];
            let weight = (at + an) / 3.0;
            // One row per gradient component: grad_t - grad_n.
            for c in 0..2 {
                let mut row: Vec<(usize, f64)> = Vec::with_capacity(6);
                row.extend((0..3).map(|k| (vt[k], gt[k][c])));
                row.extend((0..3).map(|k| (vn[k], -gn[k][c])));
                for &(i, a) in &row {
                    for &(j, b) in &row {
                        p[(i, j)] += weight * a * b;
                    }
                }
            }
        }
    }
    Ok(p)
}

/// `A'A` over the rows `keep` accepts.
fn normal_matrix(rows: &[Row], n: usize, keep: impl Fn(&Row) -> bool) -> DMatrix<f64> {
    let mut m = DMatrix::<f64>::zeros(n, n);
    for r in rows.iter().filter(|r| keep(r)) {
        for a in 0..3 {
            for b in 0..3 {
                m[(r.vertex[a], r.vertex[b])] += r.weight[a] * r.weight[b];
            }
        }
    }
    m
}

/// `A'y` over the rows `keep` accepts.
fn normal_rhs(rows: &[Row], n: usize, keep: impl Fn(&Row) -> bool) -> DVector<f64> {
    let mut b = DVector::<f64>::zeros(n);
    for r in rows.iter().filter(|r| keep(r)) {
        for a in 0..3 {
            b[r.vertex[a]] += r.weight[a] * r.value;
        }
    }
    b
}

/// Solves the symmetric system `m v = b` (Cholesky) after adding `ridge` to the diagonal, so
/// that nodes without data stay defined; `None` if it fails. The ridge is a tiny fraction of
/// the data term's mean diagonal only: one scaled with the penalty would, at large weights,
/// pull the plane the penalty leaves free toward zero.
fn solve(mut m: DMatrix<f64>, b: DVector<f64>, ridge: f64) -> Option<Vec<f64>> {
    let n = m.nrows();
    for i in 0..n {
        m[(i, i)] += ridge.max(f64::MIN_POSITIVE);
    }
    let v = m.cholesky()?.solve(&b);
    v.iter().all(|x| x.is_finite()).then(|| v.iter().copied().collect())
}

fn predict(r: &Row, v: &[f64]) -> f64 {
    (0..3).map(|k| r.weight[k] * v[r.vertex[k]]).sum()
}

/// Mean squared error of the group-`g` rows about their own mean error.
fn held_out_mse(rows: &[Row], g: usize, v: &[f64]) -> f64 {
    let errors: Vec<f64> = rows.iter().filter(|r| r.group == g).map(|r| predict(r, v) - r.value).collect();
    if errors.is_empty() {
        return f64::NAN;
    }
    let mean = errors.iter().sum::<f64>() / errors.len() as f64;
    errors.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / errors.len() as f64
}

/// A candidate from the per-group held-out MSEs (groups without points are skipped).
fn candidate(relative_weight: Option<f64>, errors: &[f64]) -> CvCandidate {
    let e: Vec<f64> = errors.iter().copied().filter(|x| !x.is_nan()).collect();
    let k = e.len().max(1) as f64;
    let mean = e.iter().sum::<f64>() / k;
    let var = e.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (k - 1.0).max(1.0);
    let se = (var / k).sqrt();
    let cv_rms_dph = mean.sqrt();
    CvCandidate { relative_weight, cv_rms_dph, cv_se_dph: (mean + se).sqrt() - cv_rms_dph }
}

/// Index of the simplest candidate (the curve is ordered simplest first) whose mean squared
/// error is within one standard error of the smallest.
fn one_standard_error(curve: &[CvCandidate]) -> usize {
    let mse = |c: &CvCandidate| c.cv_rms_dph * c.cv_rms_dph;
    let Some((best, min)) = curve
        .iter()
        .enumerate()
        .filter(|(_, c)| c.cv_rms_dph.is_finite())
        .min_by(|a, b| mse(a.1).total_cmp(&mse(b.1)))
    else {
        return 0;
    };
    let limit = (min.cv_rms_dph + min.cv_se_dph).powi(2);
    curve.iter().position(|c| mse(c) <= limit).unwrap_or(best)
}

fn rms_misfit(rows: &[Row], v: &[f64]) -> f64 {
    let sum: f64 = rows.iter().map(|r| (predict(r, v) - r.value).powi(2)).sum();
    (sum / rows.len().max(1) as f64).sqrt()
}
