//! Thinning: which calibration points become mesh nodes.
//!
//! - [`thin_paper`]: the paper's rule: every point while the temperature changes fast,
//!   every k-th once it settles.
//! - [`thin_greedy`] (default): start from the convex hull of all candidates, then
//!   repeatedly insert the candidates with the largest interpolation error (on the
//!   normalised axes, exactly as the firmware interpolates) until every candidate is
//!   within a tolerance or a node budget is reached.

use fogtemp_core::Normalisation;
use spade::{DelaunayTriangulation, FloatTriangulation, HasPosition, Point2, Triangulation};

use crate::error::CalError;
use crate::mesh::MeshPoint;

/// The paper's rule: the smoothed series is taken one point per smoothing window (every
/// `stride`-th calibration point of a run, in time order: 100 s windows of 1 s points give
/// the paper's 72 points per 2 h run); of those, keep every point with
/// `|rate| >= fast_rate_c_per_min` and every `settled_every`-th of the others. Returns indices.
pub fn thin_paper(
    points: &[MeshPoint],
    runs: &[usize],
    stride: usize,
    fast_rate_c_per_min: f64,
    settled_every: usize,
) -> Vec<usize> {
    let (every, stride) = (settled_every.max(1), stride.max(1));
    let mut seen_in_run = std::collections::HashMap::<usize, usize>::new();
    let mut settled_seen = std::collections::HashMap::<usize, usize>::new();
    let mut keep = Vec::new();
    for (i, p) in points.iter().enumerate() {
        let run = runs.get(i).copied().unwrap_or(0);
        let seen = seen_in_run.entry(run).or_insert(0);
        *seen += 1;
        if (*seen - 1) % stride != 0 {
            continue;
        }
        if p.rate_c_per_min.abs() >= fast_rate_c_per_min {
            keep.push(i);
            continue;
        }
        let settled = settled_seen.entry(run).or_insert(0);
        if *settled % every == 0 {
            keep.push(i);
        }
        *settled += 1;
    }
    keep
}

/// Settings of [`thin_greedy`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GreedyThinning {
    /// Stop when every candidate is interpolated within this, deg/h.
    pub tolerance_dph: f64,
    /// Stop at this many nodes.
    pub max_nodes: usize,
    /// Fraction of the current node count inserted per round (at least one point).
    pub batch_fraction: f64,
    /// Stop on the RMS error instead of the largest error. With noisy targets the largest
    /// error is a few noise sigmas however good the mesh is, so only the RMS can tell
    /// systematic misfit from noise.
    pub stop_on_rms: bool,
}

impl Default for GreedyThinning {
    fn default() -> Self {
        Self { tolerance_dph: 0.002, max_nodes: 600, batch_fraction: 0.1, stop_on_rms: false }
    }
}

/// Outcome of [`thin_greedy`].
#[derive(Clone, Debug, PartialEq)]
pub struct Thinned {
    /// Indices of the kept points.
    pub keep: Vec<usize>,
    /// Largest absolute interpolation error over all candidates at the end, deg/h.
    pub max_error_dph: f64,
    /// RMS interpolation error over all candidates at the end, deg/h.
    pub rms_error_dph: f64,
}

#[derive(Clone, Copy)]
struct Node {
    position: Point2<f64>,
    value: f64,
}

impl HasPosition for Node {
    type Scalar = f64;
    fn position(&self) -> Point2<f64> {
        self.position
    }
}

/// Greedy error-driven insertion (see the module docs).
///
/// # Errors
/// [`CalError::DegenerateMesh`] when the candidates do not span an area;
/// [`CalError::NonFinite`] for a NaN point.
pub fn thin_greedy(
    points: &[MeshPoint],
    normalisation: &Normalisation,
    settings: &GreedyThinning,
) -> Result<Thinned, CalError> {
    let nodes = normalised_nodes(points, normalisation)?;
    let mut keep = hull_indices(&nodes)?;
    let mut selected = vec![false; nodes.len()];
    let mut dt: DelaunayTriangulation<Node> = DelaunayTriangulation::new();
    for &i in &keep {
        selected[i] = true;
        dt.insert(nodes[i]).map_err(|_| CalError::NonFinite { what: "mesh point", index: i })?;
    }
    loop {
        let errors = interpolation_errors(&dt, &nodes);
        let (max_error_dph, rms_error_dph) = error_stats(&errors);
        let budget = settings.max_nodes.saturating_sub(keep.len());
        let error = if settings.stop_on_rms { rms_error_dph } else { max_error_dph };
        if error <= settings.tolerance_dph || budget == 0 {
            keep.sort_unstable();
            return Ok(Thinned { keep, max_error_dph, rms_error_dph });
        }
        let batch = ((keep.len() as f64 * settings.batch_fraction) as usize).clamp(1, budget);
        let mut worst: Vec<(f64, usize)> = errors
            .iter()
            .enumerate()
            .filter(|&(i, e)| !selected[i] && *e > settings.tolerance_dph)
            .map(|(i, e)| (*e, i))
            .collect();
        if worst.is_empty() {
            keep.sort_unstable();
            return Ok(Thinned { keep, max_error_dph, rms_error_dph });
        }
        let take = batch.min(worst.len());
        worst.select_nth_unstable_by(take - 1, |a, b| b.0.total_cmp(&a.0));
        for &(_, i) in &worst[..take] {
            selected[i] = true;
            keep.push(i);
            dt.insert(nodes[i]).map_err(|_| CalError::NonFinite { what: "mesh point", index: i })?;
        }
    }
}

fn normalised_nodes(points: &[MeshPoint], normalisation: &Normalisation) -> Result<Vec<Node>, CalError> {
    points
        .iter()
        .enumerate()
        .map(|(index, p)| {
            if !(p.temp_c.is_finite() && p.rate_c_per_min.is_finite() && p.value_dph.is_finite()) {
                return Err(CalError::NonFinite { what: "mesh point", index });
            }
            let (x, y) = crate::mesh::normalised(p, normalisation);
            Ok(Node { position: Point2::new(f64::from(x), f64::from(y)), value: p.value_dph })
        })
        .collect()
}

/// Indices of the points on the convex hull of all candidates (one per distinct position).
fn hull_indices(nodes: &[Node]) -> Result<Vec<usize>, CalError> {
    let mut dt: DelaunayTriangulation<Node> = DelaunayTriangulation::new();
    let mut index_of = Vec::with_capacity(nodes.len());
    for (i, n) in nodes.iter().enumerate() {
        let handle = dt.insert(*n).map_err(|_| CalError::NonFinite { what: "mesh point", index: i })?;
        if handle.index() == index_of.len() {
            index_of.push(i);
        }
    }
    if dt.num_inner_faces() == 0 {
        return Err(CalError::DegenerateMesh {
            reason: "points do not span an area",
            points: dt.num_vertices(),
        });
    }
    Ok(dt.convex_hull().map(|e| index_of[e.from().fix().index()]).collect())
}

/// |interpolated - value| for every node (0 for nodes outside the hull, which cannot
/// happen for candidates inside the hull of all candidates).
fn interpolation_errors(dt: &DelaunayTriangulation<Node>, nodes: &[Node]) -> Vec<f64> {
    let interp = dt.barycentric();
    nodes
        .iter()
        .map(|n| interp.interpolate(|v| v.data().value, n.position).map_or(0.0, |v| (v - n.value).abs()))
        .collect()
}

fn error_stats(errors: &[f64]) -> (f64, f64) {
    let max = errors.iter().copied().fold(0.0, f64::max);
    let rms = (errors.iter().map(|e| e * e).sum::<f64>() / errors.len().max(1) as f64).sqrt();
    (max, rms)
}
