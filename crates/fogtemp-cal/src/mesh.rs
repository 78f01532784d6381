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
    /// Points dropped because they made a flat triangle away from the hull (near-duplicate
    /// points; see [`MIN_SHAPE_RATIO`]), as `(temp_c, rate_c_per_min, value_dph)` after merging.
    pub dropped_flat: Vec<(f64, f64, f64)>,
    /// Points moved outward because they made a flat triangle on the hull, as the
    /// displacement `(delta_temp_c, delta_rate_c_per_min)` of each.
    pub moved_flat: Vec<(f64, f64)>,
}

/// Smallest accepted `height / longest edge` of a triangle (in the normalised plane).
/// Flatter triangles cannot be represented in f32. In a Delaunay mesh they appear on the
/// hull, where boundary points are nearly collinear (a first-order warm-up is a straight
/// line in (T, dT/dt), so the outermost runs lie along the hull): the middle vertex is
/// pushed outward by [`PUSH_RATIO`] of the long edge, a shift far below any sensor's
/// resolution, and nothing is lost. Away from the hull only near-duplicate points make
/// them; there the middle vertex is dropped (and reported).
pub const MIN_SHAPE_RATIO: f64 = 1.0e-4;

/// How far a flat hull triangle's middle vertex is pushed outward, as a fraction of the
/// triangle's longest edge (a few times [`MIN_SHAPE_RATIO`], so one push suffices).
pub const PUSH_RATIO: f64 = 4.0e-4;

/// Most rounds of dropping flat-triangle vertices before giving up.
const MAX_FLAT_ROUNDS: usize = 50;

#[derive(Clone, Copy, Debug)]
struct Node {
    position: Point2<f64>,
    /// Position before any push (equal to `position` for most nodes).
    original: Point2<f64>,
    value_dph: f64,
}

impl HasPosition for Node {
    type Scalar = f64;
    fn position(&self) -> Point2<f64> {
        self.position
    }
}

/// Identity normalisation for tests: physical (T, rate) are the normalised (x, y).
#[cfg(test)]
pub(crate) const IDENTITY: Normalisation = Normalisation {
    temp_offset_c: 0.0,
    temp_scale_per_c: 1.0,
    rate_offset_c_per_min: 0.0,
    rate_scale_per_c_per_min: 1.0,
};

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
    reject_collinear(&triangulate(&nodes)?, nodes.len())?;
    let mut dropped = Vec::new();
    for round in 0..MAX_FLAT_ROUNDS {
        let dt = triangulate(&nodes)?;
        let flat = flat_triangles(&dt);
        if flat.is_empty() {
            let mut mesh = extract(&dt, merged_duplicates);
            mesh.dropped_flat = dropped.iter().map(|n| physical(n, normalisation)).collect();
            mesh.moved_flat = nodes
                .iter()
                .filter(|n| n.position != n.original)
                .map(|n| {
                    (
                        (n.position.x - n.original.x) / f64::from(normalisation.temp_scale_per_c),
                        (n.position.y - n.original.y) / f64::from(normalisation.rate_scale_per_c_per_min),
                    )
                })
                .collect();
            return Ok(mesh);
        }
        let centroid = centroid(&nodes);
        let mut drop = vec![false; nodes.len()];
        let last_rounds = round + 3 >= MAX_FLAT_ROUNDS;
        for f in flat {
            if last_rounds {
                drop[f.middle] = true;
            } else {
                push_outward(&mut nodes[f.middle], &f, centroid);
            }
        }
        let mut index = 0;
        nodes.retain(|n| {
            let gone = drop[index];
            index += 1;
            if gone {
                dropped.push(*n);
            }
            !gone
        });
    }
    Err(CalError::DegenerateMesh {
        reason: "flat triangles remain after pushing boundary points",
        points: nodes.len(),
    })
}

/// A triangle flatter than [`MIN_SHAPE_RATIO`]: its middle vertex (opposite the longest
/// edge), that edge's ends, and the value gradient around the middle vertex (least-squares
/// plane through it and its Delaunay neighbours; `None` if they are collinear).
struct FlatTriangle {
    middle: usize,
    a: Point2<f64>,
    b: Point2<f64>,
    gradient: Option<(f64, f64)>,
}

/// A set whose triangulated area is below [`MIN_SHAPE_RATIO`] of its squared diagonal is
/// (nearly) collinear: a single warm-up run, for example. That is an error, not a mesh.
fn reject_collinear(dt: &DelaunayTriangulation<Node>, points: usize) -> Result<(), CalError> {
    let area: f64 = dt.inner_faces().map(|f| f.area()).sum();
    let (lo, hi) = dt.vertices().fold(
        (Point2::new(f64::INFINITY, f64::INFINITY), Point2::new(f64::NEG_INFINITY, f64::NEG_INFINITY)),
        |(lo, hi), v| {
            let p = v.position();
            (Point2::new(lo.x.min(p.x), lo.y.min(p.y)), Point2::new(hi.x.max(p.x), hi.y.max(p.y)))
        },
    );
    let diag2 = (hi.x - lo.x).powi(2) + (hi.y - lo.y).powi(2);
    if area < MIN_SHAPE_RATIO * diag2 {
        return Err(CalError::DegenerateMesh { reason: "the points are (nearly) collinear", points });
    }
    Ok(())
}

/// Gradient of the least-squares plane through `centre` and `neighbours` (position, value).
fn local_gradient(centre: (Point2<f64>, f64), neighbours: &[(Point2<f64>, f64)]) -> Option<(f64, f64)> {
    let rows: Vec<(f64, f64, f64)> = std::iter::once(centre)
        .chain(neighbours.iter().copied())
        .map(|(p, v)| (p.x - centre.0.x, p.y - centre.0.y, v - centre.1))
        .collect();
    let a = nalgebra::DMatrix::from_fn(rows.len(), 3, |r, c| match c {
        0 => rows[r].0,
        1 => rows[r].1,
        _ => 1.0,
    });
    let b = nalgebra::DVector::from_iterator(rows.len(), rows.iter().map(|r| r.2));
    let svd = a.svd(true, true);
    let sv = &svd.singular_values;
    if sv.min() <= 1e-9 * sv.max() {
        return None;
    }
    let x = svd.solve(&b, 0.0).ok()?;
    Some((x[0], x[1]))
}

fn centroid(nodes: &[Node]) -> Point2<f64> {
    let n = nodes.len().max(1) as f64;
    let (x, y) = nodes.iter().fold((0.0, 0.0), |(x, y), v| (x + v.position.x, y + v.position.y));
    Point2::new(x / n, y / n)
}

/// Moves `node` to its projection on line `ab` plus [`PUSH_RATIO`] of `|ab|` along the
/// normal pointing away from `centroid` (outward: flat triangles lie on the hull), rounded
/// to f32 as the firmware will see it, and corrects its value to first order with the
/// local gradient (exact for planar data).
fn push_outward(node: &mut Node, flat: &FlatTriangle, centroid: Point2<f64>) {
    let (a, b) = (flat.a, flat.b);
    let (dx, dy) = (b.x - a.x, b.y - a.y);
    let len = (dx * dx + dy * dy).sqrt();
    if len == 0.0 {
        return;
    }
    let (mut nx, mut ny) = (-dy / len, dx / len);
    if (centroid.x - a.x) * nx + (centroid.y - a.y) * ny > 0.0 {
        (nx, ny) = (-nx, -ny);
    }
    let p = node.position;
    let s = ((p.x - a.x) * dx + (p.y - a.y) * dy) / (len * len);
    let offset = PUSH_RATIO * len;
    let x = a.x + s * dx + nx * offset;
    let y = a.y + s * dy + ny * offset;
    let moved = Point2::new(f64::from(x as f32), f64::from(y as f32));
    if let Some((gx, gy)) = flat.gradient {
        node.value_dph += gx * (moved.x - p.x) + gy * (moved.y - p.y);
    }
    node.position = moved;
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

/// Every triangle flatter than [`MIN_SHAPE_RATIO`] (vertex indices are insertion order).
fn flat_triangles(dt: &DelaunayTriangulation<Node>) -> Vec<FlatTriangle> {
    let mut seen = std::collections::BTreeSet::new();
    let mut flat = Vec::new();
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
        if area2 >= MIN_SHAPE_RATIO * l2 {
            continue;
        }
        let vertex = face.vertices()[longest];
        let middle = vertex.fix().index();
        if seen.insert(middle) {
            let neighbours: Vec<(Point2<f64>, f64)> =
                vertex.out_edges().map(|e| (e.to().position(), e.to().data().value_dph)).collect();
            flat.push(FlatTriangle {
                middle,
                a: p[(longest + 1) % 3],
                b: p[(longest + 2) % 3],
                gradient: local_gradient((vertex.position(), vertex.data().value_dph), &neighbours),
            });
        }
    }
    flat
}

/// A node back in physical units (inverse normalisation, f64).
fn physical(n: &Node, nz: &Normalisation) -> (f64, f64, f64) {
    let (temp_c, rate_c_per_min) = to_physical(nz, n.position.x, n.position.y);
    (temp_c, rate_c_per_min, n.value_dph)
}

/// The inverse of the normalisation (f64): `(temp_c, rate_c_per_min)` of a point `(x, y)`
/// of the normalised plane.
pub fn to_physical(nz: &Normalisation, x: f64, y: f64) -> (f64, f64) {
    (
        x / f64::from(nz.temp_scale_per_c) + f64::from(nz.temp_offset_c),
        y / f64::from(nz.rate_scale_per_c_per_min) + f64::from(nz.rate_offset_c_per_min),
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
        .map(|(x, y, sum, n)| {
            let position = Point2::new(f64::from(x), f64::from(y));
            Node { position, original: position, value_dph: sum / n as f64 }
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
    MeshModel {
        vertices,
        triangles,
        neighbours,
        hull,
        merged_duplicates,
        dropped_flat: Vec::new(),
        moved_flat: Vec::new(),
    }
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
