//! Compact triangle mesh for the blob, extracted from a `spade` Delaunay triangulation
//! built on the normalised axes (so triangles are well shaped whatever the physical units).

use std::collections::HashMap;

use fogtemp_core::{Normalisation, Vertex};
use spade::{DelaunayTriangulation, HasPosition, Point2, Triangulation};

use crate::error::CalError;

/// A calibration point in physical units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MeshPoint {
    /// Temperature, deg C.
    pub temp_c: f64,
    /// Temperature rate, deg C/min.
    pub rate_c_per_min: f64,
    /// Bias (or residual) at this point, deg/h.
    pub value_dph: f64,
}

/// The mesh as the blob stores it: vertices in the normalised plane, counter-clockwise
/// triangles, neighbours (neighbour k across the edge opposite vertex k) and the hull
/// as `(triangle, edge)` pairs in counter-clockwise order.
#[derive(Clone, Debug, PartialEq)]
pub struct MeshModel {
    /// Vertices, normalised position and value.
    pub vertices: Vec<Vertex>,
    /// Vertex indices per triangle, counter-clockwise.
    pub triangles: Vec<[u32; 3]>,
    /// Neighbour triangles, [`fogtemp_core::wire::NO_NEIGHBOUR`] on the hull.
    pub neighbours: Vec<[u32; 3]>,
    /// Hull edges, counter-clockwise.
    pub hull: Vec<(u32, u32)>,
    /// Input points merged into another because they normalise to the same f32 position.
    pub merged_duplicates: usize,
    /// Points dropped because they made a flat triangle on the hull (see [`MIN_SHAPE_RATIO`]),
    /// as `(temp_c, rate_c_per_min, value_dph)` after merging.
    pub dropped_flat: Vec<(f64, f64, f64)>,
}

/// Smallest accepted `height / longest edge` of a triangle (in the normalised plane).
/// Flatter triangles (only possible on the hull of a Delaunay mesh, from nearly collinear
/// boundary points) cannot be represented in f32: their middle vertex is dropped.
pub const MIN_SHAPE_RATIO: f64 = 1.0e-4;

/// Most rounds of dropping flat-triangle vertices before giving up.
const MAX_FLAT_ROUNDS: usize = 50;

#[derive(Clone, Copy, Debug)]
struct Node {
    position: Point2<f64>,
    value_dph: f64,
}

impl HasPosition for Node {
    type Scalar = f64;
    fn position(&self) -> Point2<f64> {
        self.position
    }
}

/// Normalised f32 position of a point, exactly as the firmware computes it.
pub fn normalised(point: &MeshPoint, normalisation: &Normalisation) -> (f32, f32) {
    normalisation.apply(point.temp_c as f32, point.rate_c_per_min as f32)
}

/// Delaunay-triangulates `points` on the normalised axes. Points that land on the same
/// f32 position are merged (their values averaged) and counted in `merged_duplicates`.
///
/// # Errors
/// [`CalError::NonFinite`] for a NaN/infinite input, [`CalError::DegenerateMesh`] for
/// fewer than 3 distinct points or a collinear set.
pub fn build_mesh(points: &[MeshPoint], normalisation: &Normalisation) -> Result<MeshModel, CalError> {
    let (mut nodes, merged_duplicates) = merge_duplicates(points, normalisation)?;
    let mut dropped = Vec::new();
    for _ in 0..MAX_FLAT_ROUNDS {
        let dt = triangulate(&nodes)?;
        let flat = flat_triangle_middles(&dt);
        if flat.is_empty() {
            let mut mesh = extract(&dt, merged_duplicates);
            mesh.dropped_flat = dropped.iter().map(|n: &Node| physical(n, normalisation)).collect();
            return Ok(mesh);
        }
        let mut keep = vec![true; nodes.len()];
        for i in flat {
            keep[i] = false;
        }
        let mut index = 0;
        nodes.retain(|n| {
            let k = keep[index];
            index += 1;
            if !k {
                dropped.push(*n);
            }
            k
        });
    }
    Err(CalError::DegenerateMesh {
        reason: "flat triangles remain after dropping boundary points",
        points: nodes.len(),
    })
}

fn triangulate(nodes: &[Node]) -> Result<DelaunayTriangulation<Node>, CalError> {
    if nodes.len() < 3 {
        return Err(CalError::DegenerateMesh { reason: "fewer than 3 distinct points", points: nodes.len() });
    }
    let mut dt: DelaunayTriangulation<Node> = DelaunayTriangulation::new();
    for (index, node) in nodes.iter().enumerate() {
        dt.insert(*node).map_err(|_| CalError::NonFinite { what: "mesh point position", index })?;
    }
    if dt.num_inner_faces() == 0 {
        return Err(CalError::DegenerateMesh { reason: "all points are collinear", points: nodes.len() });
    }
    Ok(dt)
}

/// For each triangle flatter than [`MIN_SHAPE_RATIO`], the vertex opposite its longest
/// edge (the one lying almost on that edge). Vertex indices are insertion order.
fn flat_triangle_middles(dt: &DelaunayTriangulation<Node>) -> std::collections::BTreeSet<usize> {
    let mut middles = std::collections::BTreeSet::new();
    for face in dt.inner_faces() {
        let p = face.positions();
        let edge2 = |i: usize| {
            let (a, b) = (p[(i + 1) % 3], p[(i + 2) % 3]);
            (a.x - b.x).powi(2) + (a.y - b.y).powi(2)
        };
        let (longest, l2) =
            (0..3).map(|i| (i, edge2(i))).fold((0, 0.0), |m, e| if e.1 > m.1 { e } else { m });
        let area2 = ((p[1].x - p[0].x) * (p[2].y - p[0].y) - (p[1].y - p[0].y) * (p[2].x - p[0].x)).abs();
        // height / longest = area2 / longest^2
        if area2 < MIN_SHAPE_RATIO * l2 {
            middles.insert(face.vertices()[longest].fix().index());
        }
    }
    middles
}

/// A node back in physical units (inverse normalisation, f64).
fn physical(n: &Node, nz: &Normalisation) -> (f64, f64, f64) {
    (
        n.position.x / f64::from(nz.temp_scale_per_c) + f64::from(nz.temp_offset_c),
        n.position.y / f64::from(nz.rate_scale_per_c_per_min) + f64::from(nz.rate_offset_c_per_min),
        n.value_dph,
    )
}

fn merge_duplicates(
    points: &[MeshPoint],
    normalisation: &Normalisation,
) -> Result<(Vec<Node>, usize), CalError> {
    let mut slots: HashMap<(u32, u32), usize> = HashMap::new();
    let mut sums: Vec<(f32, f32, f64, usize)> = Vec::new();
    for (index, p) in points.iter().enumerate() {
        if !(p.temp_c.is_finite() && p.rate_c_per_min.is_finite() && p.value_dph.is_finite()) {
            return Err(CalError::NonFinite { what: "mesh point", index });
        }
        let (x, y) = normalised(p, normalisation);
        // +0.0 and -0.0 are one position.
        let key = ((x + 0.0).to_bits(), (y + 0.0).to_bits());
        let slot = *slots.entry(key).or_insert_with(|| {
            sums.push((x, y, 0.0, 0));
            sums.len() - 1
        });
        if let Some(s) = sums.get_mut(slot) {
            s.2 += p.value_dph;
            s.3 += 1;
        }
    }
    let merged = points.len() - sums.len();
    let nodes = sums
        .into_iter()
        .map(|(x, y, sum, n)| Node {
            position: Point2::new(f64::from(x), f64::from(y)),
            value_dph: sum / n as f64,
        })
        .collect();
    Ok((nodes, merged))
}

fn extract(dt: &DelaunayTriangulation<Node>, merged_duplicates: usize) -> MeshModel {
    let vertices: Vec<Vertex> = dt
        .vertices()
        .map(|v| Vertex {
            x: v.position().x as f32,
            y: v.position().y as f32,
            value_dph: v.data().value_dph as f32,
        })
        .collect();
    // spade face index -> our triangle index (spade's face 0 is the outer face).
    let mut face_to_triangle = vec![fogtemp_core::wire::NO_NEIGHBOUR; dt.num_all_faces()];
    for (t, face) in dt.inner_faces().enumerate() {
        if let Some(slot) = face_to_triangle.get_mut(face.fix().index()) {
            *slot = t as u32;
        }
    }
    let mut triangles = Vec::with_capacity(dt.num_inner_faces());
    let mut neighbours = Vec::with_capacity(dt.num_inner_faces());
    let mut hull_by_start: HashMap<u32, (u32, u32)> = HashMap::new();
    for (t, face) in dt.inner_faces().enumerate() {
        let vs = face.vertices().map(|v| v.fix().index() as u32);
        // spade: edge k runs from vertex k to k+1, so the edge opposite vertex k is edge k+1.
        let edges = face.adjacent_edges();
        let mut nb = [fogtemp_core::wire::NO_NEIGHBOUR; 3];
        for (k, slot) in nb.iter_mut().enumerate() {
            let across = edges[(k + 1) % 3].rev().face();
            if let Some(inner) = across.as_inner() {
                *slot = face_to_triangle
                    .get(inner.fix().index())
                    .copied()
                    .unwrap_or(fogtemp_core::wire::NO_NEIGHBOUR);
            } else {
                hull_by_start.insert(vs[(k + 1) % 3], (t as u32, k as u32));
            }
        }
        triangles.push(vs);
        neighbours.push(nb);
    }
    let hull = chain_hull(&hull_by_start, &triangles);
    MeshModel { vertices, triangles, neighbours, hull, merged_duplicates, dropped_flat: Vec::new() }
}

/// Orders hull edges counter-clockwise by following end vertex to start vertex.
fn chain_hull(hull_by_start: &HashMap<u32, (u32, u32)>, triangles: &[[u32; 3]]) -> Vec<(u32, u32)> {
    let Some(&start) = hull_by_start.keys().min() else { return Vec::new() };
    let mut hull = Vec::with_capacity(hull_by_start.len());
    let mut at = start;
    while let Some(&(t, e)) = hull_by_start.get(&at) {
        hull.push((t, e));
        at = triangles[t as usize][(e as usize + 2) % 3];
        if at == start || hull.len() > hull_by_start.len() {
            break;
        }
    }
    hull
}
