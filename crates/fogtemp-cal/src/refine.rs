//! Steiner nodes where the triangulation is too coarse to carry the smooth part of the bias.
//!
//! Greedy thinning places nodes on the calibration paths only. Between paths (a validation run
//! crossing the gap between two chamber runs, a corner of the convex hull no run reached) the
//! triangles are large, and a piecewise-linear surface over them cannot follow the polynomial
//! part b(T) + c(T) dT/dt that the node fit leaves free: there the mesh is the *linear
//! interpolation* of that surface, which errs by the surface's curvature times the squared
//! triangle size. Seen on the testbed (seed 8, `static_shape`): a validation run through such
//! a gap compensated 1.6x worse than with the polynomial, with the smoothing weight at its
//! largest (the node values already the polynomial's own terms).
//!
//! The remedy is the standard one of mesh refinement: for every triangle over which the linear
//! interpolation of a reference surface (the polynomial the data selected) differs from the
//! surface by more than a tolerance, insert a node where it differs most among the centroid
//! and the edge midpoints (an edge's midpoint when the edge is at fault: a centroid never
//! splits an edge, and a hull edge is never flipped away), re-triangulate, repeat.
//! The node values are then fitted as usual (`mesh_fit`): where no data is near, the penalty,
//! which leaves the polynomial's terms free, makes them that surface's values. The tolerance is
//! a fraction of the smoothed target's noise: an interpolation error `d` adds to a validation
//! error `s` in quadrature, `sqrt(s^2 + d^2)`, so `d <= s / 10` costs at most 0.5 %.

use fogtemp_core::Normalisation;

use crate::error::CalError;
use crate::mesh::{build_mesh, to_physical, MeshModel, MeshPoint};

/// Interpolation tolerance as a fraction of the smoothed target's noise (see the module docs).
pub const SURFACE_TOLERANCE_NOISE: f64 = 0.1;

/// Most rounds of inserting nodes (each round re-triangulates).
pub const MAX_ROUNDS: usize = 12;

/// What refinement did.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Refinement {
    /// Steiner nodes inserted.
    pub added_nodes: usize,
    /// Largest |linear interpolation - surface| over the final mesh's triangles (centroid and
    /// edge midpoints), deg/h.
    pub worst_interpolation_error_dph: f64,
    /// The tolerance it aimed at, deg/h.
    pub tolerance_dph: f64,
}

/// A refined mesh, the mesh of the nodes as given, and what refinement did.
#[derive(Clone, Debug, PartialEq)]
pub struct Refined {
    /// The mesh with the Steiner nodes.
    pub mesh: MeshModel,
    /// The mesh of the nodes as given (before any Steiner node).
    pub coarse: MeshModel,
    /// What refinement did.
    pub report: Refinement,
}

/// Builds the mesh of `nodes` and inserts Steiner nodes (valued by `surface`) in triangles over
/// which the linear interpolation of `surface` (a function of the normalised `(x, y)`) misses it
/// by more than `tolerance_dph`, each at the worst of the triangle's centroid and edge
/// midpoints, at most `max_added` of them, worst first.
///
/// # Errors
/// As [`build_mesh`].
pub fn refine_for_surface(
    nodes: &mut Vec<MeshPoint>,
    normalisation: &Normalisation,
    surface: &dyn Fn(f64, f64) -> f64,
    tolerance_dph: f64,
    max_added: usize,
) -> Result<Refined, CalError> {
    let mut added_nodes = 0;
    let mut round = 0;
    let mut coarse = None;
    loop {
        let mesh = build_mesh(nodes, normalisation)?;
        let coarse = coarse.get_or_insert_with(|| mesh.clone());
        let mut errors: Vec<(f64, (f64, f64))> =
            mesh.triangles.iter().map(|&t| interpolation_error(&mesh, t, surface)).collect();
        let worst = errors.iter().map(|e| e.0).fold(0.0, f64::max);
        let budget = max_added - added_nodes;
        if round == MAX_ROUNDS || budget == 0 || worst <= tolerance_dph {
            let report = Refinement { added_nodes, worst_interpolation_error_dph: worst, tolerance_dph };
            return Ok(Refined { mesh, coarse: coarse.clone(), report });
        }
        errors.retain(|e| e.0 > tolerance_dph);
        errors.sort_by(|a, b| b.0.total_cmp(&a.0));
        // An edge midpoint is the worst point of both triangles sharing the edge: insert it once.
        let mut seen = std::collections::HashSet::new();
        errors.retain(|e| seen.insert((e.1 .0.to_bits(), e.1 .1.to_bits())));
        for &(_, (x, y)) in errors.iter().take(budget) {
            let (temp_c, rate_c_per_min) = to_physical(normalisation, x, y);
            nodes.push(MeshPoint { temp_c, rate_c_per_min, value_dph: surface(x, y) });
            added_nodes += 1;
        }
        round += 1;
    }
}

/// A refined mesh's vertex values as affine functions of the coarse mesh's: refined vertex `k`
/// is `sum_j weight[j] * coarse[vertex[j]] + constant_dph`.
#[derive(Clone, Debug, PartialEq)]
pub struct Tie {
    /// The coarse mesh (the thinned nodes' own).
    pub coarse: MeshModel,
    /// Per refined vertex: coarse vertices, their weights, and the constant, deg/h.
    pub map: Vec<([usize; 3], [f64; 3], f64)>,
}

impl Tie {
    /// The refined mesh's vertex values from the coarse mesh's (`coarse_values[j]` of coarse
    /// vertex `j`; a missing one counts as zero).
    pub fn apply(&self, coarse_values: &[f64]) -> Vec<f64> {
        let value = |j: usize| coarse_values.get(j).copied().unwrap_or(0.0);
        self.map
            .iter()
            .map(|(v, w, constant)| (0..3).map(|j| w[j] * value(v[j])).sum::<f64>() + constant)
            .collect()
    }
}

/// Ties every vertex of `fine` to the triangle of `coarse` that holds it (the nearest one,
/// weights clamped, for a vertex that f32 rounding or a flat-triangle push put just outside):
/// its value is the coarse interpolation plus what `surface` has there beyond the coarse
/// interpolation of `surface` (zero at a coarse vertex).
pub fn tie(fine: &MeshModel, coarse: MeshModel, surface: &dyn Fn(f64, f64) -> f64) -> Tie {
    let transforms: Vec<_> =
        coarse.triangles.iter().map(|&t| crate::blob::triangle_transform(&coarse, t)).collect();
    let at = |k: usize| coarse.vertices.get(k).map_or((0.0, 0.0), |v| (f64::from(v.x), f64::from(v.y)));
    let map = fine
        .vertices
        .iter()
        .map(|v| {
            let (x, y) = (f64::from(v.x), f64::from(v.y));
            let Some((vertex, weight)) = holding_triangle(&coarse, &transforms, x, y) else {
                return ([0; 3], [0.0; 3], surface(x, y));
            };
            if let Some(j) = (0..3).find(|&j| weight[j] >= 1.0 - SNAP) {
                return ([vertex[j]; 3], [1.0, 0.0, 0.0], 0.0);
            }
            let interpolated: f64 = (0..3)
                .map(|j| {
                    weight[j] * {
                        let (cx, cy) = at(vertex[j]);
                        surface(cx, cy)
                    }
                })
                .sum();
            (vertex, weight, surface(x, y) - interpolated)
        })
        .collect();
    Tie { coarse, map }
}

/// A barycentric weight this close to one is the vertex itself (a coarse node kept as is).
const SNAP: f64 = 1e-9;

/// The triangle whose smallest barycentric weight at `(x, y)` is largest (the one holding
/// the point, or the nearest in that sense), with its weights clamped to be non-negative.
fn holding_triangle(
    mesh: &MeshModel,
    transforms: &[Option<crate::blob::TriangleTransform>],
    x: f64,
    y: f64,
) -> Option<([usize; 3], [f64; 3])> {
    let mut best: Option<(usize, [f64; 3], f64)> = None;
    for (t, tf) in transforms.iter().enumerate() {
        let Some(tf) = tf else { continue };
        let l = tf.barycentric(x, y);
        let worst = l.iter().copied().fold(f64::INFINITY, f64::min);
        if best.as_ref().is_none_or(|b| worst > b.2) {
            best = Some((t, l, worst));
        }
    }
    let (t, l, _) = best?;
    let clamped = l.map(|w| w.max(0.0));
    let sum: f64 = clamped.iter().sum();
    let tri = mesh.triangles.get(t)?;
    (sum > 0.0).then(|| (tri.map(|v| v as usize), clamped.map(|w| w / sum)))
}

/// Largest |linear interpolation - surface| of triangle `tri` at its centroid and edge
/// midpoints, and where (normalised).
fn interpolation_error(
    mesh: &MeshModel,
    tri: [u32; 3],
    surface: &dyn Fn(f64, f64) -> f64,
) -> (f64, (f64, f64)) {
    let corner = |k: usize| {
        let v = mesh.vertices.get(tri[k] as usize);
        v.map_or((f64::NAN, f64::NAN), |v| (f64::from(v.x), f64::from(v.y)))
    };
    let p = [corner(0), corner(1), corner(2)];
    let f = p.map(|(x, y)| surface(x, y));
    let centroid = ((p[0].0 + p[1].0 + p[2].0) / 3.0, (p[0].1 + p[1].1 + p[2].1) / 3.0);
    let mut worst = ((surface(centroid.0, centroid.1) - (f[0] + f[1] + f[2]) / 3.0).abs(), centroid);
    for (a, b) in [(0, 1), (1, 2), (2, 0)] {
        // Ordered ends, so both triangles of an edge compute the same midpoint bits.
        let (lo, hi) = if p[a] <= p[b] { (p[a], p[b]) } else { (p[b], p[a]) };
        let mid = ((lo.0 + hi.0) / 2.0, (lo.1 + hi.1) / 2.0);
        let error = (surface(mid.0, mid.1) - (f[a] + f[b]) / 2.0).abs();
        if error > worst.0 {
            worst = (error, mid);
        }
    }
    worst
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::mesh::IDENTITY;

    fn square_corners(surface: impl Fn(f64, f64) -> f64) -> Vec<MeshPoint> {
        [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
            .map(|(t, r)| MeshPoint { temp_c: t, rate_c_per_min: r, value_dph: surface(t, r) })
            .to_vec()
    }

    #[test]
    fn a_plane_needs_no_node() {
        let plane = |x: f64, y: f64| 0.3 + 2.0 * x - y;
        let mut nodes = square_corners(plane);
        let Refined { mesh, report, .. } =
            refine_for_surface(&mut nodes, &IDENTITY, &plane, 1e-9, 100).expect("mesh");
        assert_eq!(report.added_nodes, 0);
        assert_eq!(mesh.vertices.len(), 4);
        assert!(report.worst_interpolation_error_dph < 1e-12, "{report:?}");
    }

    /// x^2 over a triangle: the linear interpolation errs at an edge midpoint by h^2 / 4
    /// for an edge of x-extent h (closed form of (x_a^2 + x_b^2)/2 - ((x_a + x_b)/2)^2).
    #[test]
    fn a_parabola_is_refined_to_the_tolerance() {
        let parabola = |x: f64, _y: f64| x * x;
        let mut nodes = square_corners(parabola);
        let coarse =
            refine_for_surface(&mut nodes.clone(), &IDENTITY, &parabola, 1e-3, 0).expect("mesh").report;
        // The square's edges and diagonal span 2 in x: error (2^2)/4 = 1.
        assert!((coarse.worst_interpolation_error_dph - 1.0).abs() < 1e-12, "{coarse:?}");
        let tolerance = 0.05;
        let Refined { mesh, report: fine, .. } =
            refine_for_surface(&mut nodes, &IDENTITY, &parabola, tolerance, 10_000).expect("mesh");
        assert!(fine.added_nodes > 0);
        assert_eq!(mesh.vertices.len(), 4 + fine.added_nodes);
        // Halving every x-extent 3 times brings h^2 / 4 from 1 to 1/64 < 0.05; the rounds suffice.
        assert!(fine.worst_interpolation_error_dph <= tolerance, "{fine:?}");
        // An independent check of the reported figure: the error at every triangle's
        // centroid is within it (closed form: x^2 minus the mean of the corners' x^2).
        for t in &mesh.triangles {
            let xs = t.map(|k| f64::from(mesh.vertices[k as usize].x));
            let centroid_x = xs.iter().sum::<f64>() / 3.0;
            let linear = xs.iter().map(|x| x * x).sum::<f64>() / 3.0;
            assert!(linear - centroid_x * centroid_x <= tolerance + 1e-9);
        }
        // Steiner nodes carry the surface's value.
        for v in &mesh.vertices {
            assert!((f64::from(v.value_dph) - f64::from(v.x) * f64::from(v.x)).abs() < 1e-6);
        }
    }

    #[test]
    fn the_budget_caps_the_nodes() {
        let bumpy = |x: f64, y: f64| (3.0 * x).sin() * (2.0 * y).cos();
        let mut nodes = square_corners(bumpy);
        let Refined { mesh, report, .. } =
            refine_for_surface(&mut nodes, &IDENTITY, &bumpy, 1e-6, 7).expect("mesh");
        assert_eq!(report.added_nodes, 7);
        assert_eq!(mesh.vertices.len(), 11);
    }

    /// The tie reproduces a surface exactly: with the coarse vertices valued by the surface,
    /// every refined vertex's tied value is the surface there (the constant is defined so),
    /// and a coarse vertex kept as is ties to itself alone.
    #[test]
    fn the_tie_carries_the_surface_to_every_refined_vertex() {
        let surface = |x: f64, y: f64| 0.2 + x * x - 0.5 * x * y + 0.3 * y * y * y;
        let mut nodes: Vec<MeshPoint> =
            [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0), (0.3, -0.2), (-0.4, 0.5)]
                .map(|(t, r)| MeshPoint { temp_c: t, rate_c_per_min: r, value_dph: surface(t, r) })
                .to_vec();
        let refined = refine_for_surface(&mut nodes, &IDENTITY, &surface, 0.01, 200).expect("mesh");
        assert!(refined.report.added_nodes > 0);
        let coarse_values: Vec<f64> =
            refined.coarse.vertices.iter().map(|v| surface(f64::from(v.x), f64::from(v.y))).collect();
        let tie = tie(&refined.mesh, refined.coarse.clone(), &surface);
        assert_eq!(tie.map.len(), refined.mesh.vertices.len());
        let applied = tie.apply(&coarse_values);
        let mut kept = 0;
        for ((v, (_, weight, constant)), tied) in refined.mesh.vertices.iter().zip(&tie.map).zip(applied) {
            let truth = surface(f64::from(v.x), f64::from(v.y));
            assert!((tied - truth).abs() < 1e-12, "{tied} vs {truth}");
            assert!((weight.iter().sum::<f64>() - 1.0).abs() < 1e-12);
            if *constant == 0.0 && weight[0] == 1.0 {
                kept += 1;
            }
        }
        assert_eq!(kept, refined.coarse.vertices.len(), "every coarse vertex ties to itself");
        // Linear in the coarse values: adding a plane to them adds the same plane (which
        // barycentric weights reproduce exactly) to every refined vertex.
        let plane = |x: f64, y: f64| 0.7 - 0.2 * x + 0.4 * y;
        let shifted: Vec<f64> = refined
            .coarse
            .vertices
            .iter()
            .zip(&coarse_values)
            .map(|(v, c)| c + plane(f64::from(v.x), f64::from(v.y)))
            .collect();
        for (v, tied) in refined.mesh.vertices.iter().zip(tie.apply(&shifted)) {
            let (x, y) = (f64::from(v.x), f64::from(v.y));
            assert!((tied - surface(x, y) - plane(x, y)).abs() < 1e-12);
        }
    }
}
