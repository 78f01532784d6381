//! The mesh continued linearly beyond its hull ([`crate::OutsidePolicy::LinearFromBoundary`]):
//! the first-order continuation from the nearest hull point, the idea of the polynomial's
//! `PolyOutside::LinearFromBoundary` (its tangent plane at the nearest boundary point).
//!
//! For a query `p` outside the hull with nearest hull point `q`, the value is
//! `m(q) + g(q) . (p - q)`, with `m(q)` the held value (linear along the hull edge) and
//! `g(q)` the gradient of a weighted least-squares plane through the mesh nodes around `q`:
//! weights `(1 - r^2 / R^2)^2` for a node at distance `r < R` from `q`, with
//! `R = GRADIENT_RADIUS` (normalised units).
//!
//! Why not a triangle's own gradient: a mesh's nodes carry noise (`sigma` each), and a
//! gradient from nodes spread over a baseline `b` carries `sigma / b` of it, which the
//! continuation multiplies by the distance. Along the hull the baselines are short: Delaunay
//! hull triangles are slivers, and a settled run end puts tens of nodes within a fraction of
//! a degree. A fixed radius makes the baseline a fixed share of the calibrated span (the
//! normalisation maps the calibration points' bounding box to `[-1, 1]^2`, so `R = 0.5` is a
//! quarter of each axis's span), whatever the local node spacing. The biweight makes `g(q)`
//! continuous in `q`, and `q` is continuous in `p`, so the value is continuous everywhere,
//! and equal to the held value on the hull. For a plane mesh every weighted fit is the
//! plane, so the continuation is exact.
//!
//! Where the nodes within `R` do not span a plane (their weighted positions' correlation
//! `|rho| > 0.995`, or a single node) the fit uses every node with equal weights (the mesh's overall linear trend); a
//! mesh whose nodes do not span a plane cannot be written.
//!
//! Cost: one pass over the vertices per outside query (O(V), no allocation), plus the
//! nearest hull point (`src/hull.rs`, a scan of every hull edge where that is not certified).
//!
//! ## Stored gradients ([`crate::OutsidePolicy::StoredGradients`])
//!
//! The same continuation `m(q) + g(q) . (p - q)` without the pass over the nodes: the writer
//! stores `g` at each hull vertex (the biweight fit above around that vertex, computed in f64
//! from the stored f32 nodes; zero where not even all nodes span a plane, so the value is held
//! there, as the query-time policy holds it when it finds no gradient), and on a hull edge `g` is linear between its two vertices'
//! gradients. Why per hull vertex and linear along the edge: it is the one piecewise-linear
//! rule that keeps `g(q)` continuous along the hull (at a vertex both edges give that
//! vertex's gradient), so the value stays continuous in `p` and equal to the held value on the
//! hull; it needs H stored pairs (the hull's own size) and no search beyond the nearest hull
//! point; and it keeps every property that does not depend on where between two vertices the
//! fit is taken: a plane's every fit is the plane, so a plane is still continued exactly. What
//! it gives up: on a long hull edge the gradient in its middle is interpolated, not fitted
//! there (the query-time policy's fit at the middle sees other nodes).
//!
//! The writer numbers the hull vertices first, in hull order (vertex h starts hull edge h,
//! validated), so a gradient is found by vertex index as well as by hull index: a walk that
//! leaves the mesh across a hull edge whose normal strip holds the query (most outside
//! queries) needs no search at all. Cost per outside query: O(1) there, else the nearest hull
//! point (O(log H) typically) and O(1).

use crate::hull::{self, cyclic, dot, positive, sub, Nearest, P};
use crate::mesh::{edge_nearest, Mesh, Vertex};

/// Radius of the nodes that set the continuation's gradient, normalised units (a quarter of
/// the calibrated span of each axis; see the module documentation).
pub const GRADIENT_RADIUS: f32 = 0.5;

/// The continued value at an outside query `(x, y)`, or `None` when the nearest hull point
/// cannot be found (a non-finite query, a broken hull); the caller then holds the hull value.
pub(crate) fn linear_value(mesh: &Mesh<'_>, x: f32, y: f32) -> Option<f32> {
    let foot = Foot::of(mesh, x, y)?;
    let g = local_gradient(mesh, foot.q)?;
    Some(foot.held + dot(g, sub([x, y], foot.q)))
}

/// The value of [`crate::OutsidePolicy::StoredGradients`] at an outside query `(x, y)`: the
/// held value plus the stored gradient, linear along the nearest hull edge, times the offset
/// from the nearest hull point. `None` as for [`linear_value`], or when a gradient is missing
/// (a blob of another policy).
pub(crate) fn stored_gradient_value(mesh: &Mesh<'_>, x: f32, y: f32) -> Option<f32> {
    let foot = Foot::of(mesh, x, y)?;
    // Hull vertex h is vertex h (validated), so edge h runs from vertex h to vertex h + 1.
    let end = if foot.along > 0.0 { cyclic(foot.edge, 1, mesh.hull_edge_count()) } else { foot.edge };
    stored_continuation(mesh, foot.edge, end, foot.along, foot.q, foot.held, x, y)
}

/// [`stored_gradient_value`] for a query a walk took out of the mesh across edge `k` of
/// triangle `t`: where the nearest hull point lies on that edge (most outside queries of a
/// fine mesh), straight from it, with its two vertices' gradients (their vertex indices are
/// their hull indices); elsewhere the search. The same foot either way (the certificates are
/// disjoint), so the same value.
pub(crate) fn stored_gradient_value_after_walk(
    mesh: &Mesh<'_>,
    t: u32,
    k: usize,
    x: f32,
    y: f32,
) -> Option<f32> {
    match hull::foot_on_crossed_edge(mesh, t, k, x, y) {
        Some((from, to, s, q, held)) => stored_continuation(mesh, from, to, s, q, held, x, y),
        None => stored_gradient_value(mesh, x, y),
    }
}

/// `held + g . (p - q)` with `g` linear from hull vertex `from`'s gradient (at `s = 0`) to
/// `to`'s (at `s = 1`).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn stored_continuation(
    mesh: &Mesh<'_>,
    from: u32,
    to: u32,
    s: f32,
    q: P,
    held: f32,
    x: f32,
    y: f32,
) -> Option<f32> {
    let start = mesh.hull_gradient(from)?;
    let g = if s > 0.0 {
        let end = mesh.hull_gradient(to)?;
        [start[0] + s * (end[0] - start[0]), start[1] + s * (end[1] - start[1])]
    } else {
        start
    };
    Some(held + dot(g, sub([x, y], q)))
}

/// The nearest hull point of an outside query.
struct Foot {
    /// The hull edge it lies on, or whose start vertex it is.
    edge: u32,
    /// Its parameter along that edge (0 at the start vertex).
    along: f32,
    /// Its position.
    q: P,
    /// The held value there (linear along the edge).
    held: f32,
}

impl Foot {
    /// The nearest hull point of `(x, y)`, certified (`src/hull.rs`) or by scanning the hull;
    /// `None` for a non-finite query or a broken hull.
    fn of(mesh: &Mesh<'_>, x: f32, y: f32) -> Option<Foot> {
        if !(x.is_finite() && y.is_finite()) {
            return None;
        }
        match hull::nearest_edge(mesh, x, y).or_else(|| nearest_by_scan(mesh, x, y))? {
            Nearest::Edge(h) => {
                let (a, b) = mesh.hull_edge_vertices(h)?;
                let e = sub([b.x, b.y], [a.x, a.y]);
                let len2 = dot(e, e);
                let s =
                    if len2 > 0.0 { (dot(sub([x, y], [a.x, a.y]), e) / len2).clamp(0.0, 1.0) } else { 0.0 };
                let q = [a.x + s * e[0], a.y + s * e[1]];
                Some(Foot { edge: h, along: s, q, held: edge_nearest(&a, &b, x, y).1 })
            }
            Nearest::Vertex(h) => {
                let v = mesh.vertex(mesh.hull_start_index(h)?)?;
                Some(Foot { edge: h, along: 0.0, q: [v.x, v.y], held: v.value_dph })
            }
        }
    }
}

/// Gradient at `q` (see the module documentation): the biweight fit within
/// [`GRADIENT_RADIUS`], else the equal-weight fit of every node.
fn local_gradient(mesh: &Mesh<'_>, q: P) -> Option<P> {
    let r2 = GRADIENT_RADIUS * GRADIENT_RADIUS;
    let biweight = |v: &Vertex| {
        let d2 = dot(sub([v.x, v.y], q), sub([v.x, v.y], q));
        if d2 < r2 {
            let u = 1.0 - d2 / r2;
            u * u
        } else {
            0.0
        }
    };
    weighted_gradient(mesh, biweight).or_else(|| weighted_gradient(mesh, |_| 1.0))
}

/// Gradient `(a, b)` of the plane `v = a x + b y + c` fitted to the mesh nodes by weighted
/// least squares (weights `weight(node)`); two passes, the moments centred on the weighted
/// mean so f32 keeps its digits; `None` when the weighted positions do not span a plane.
fn weighted_gradient(mesh: &Mesh<'_>, weight: impl Fn(&Vertex) -> f32) -> Option<P> {
    let nodes = || (0..mesh.vertex_count()).filter_map(|i| mesh.vertex(i)).map(|v| (weight(&v), v));
    let (mut sw, mut sx, mut sy, mut sv) = (0.0f32, 0.0f32, 0.0f32, 0.0f32);
    for (w, v) in nodes().filter(|(w, _)| *w > 0.0) {
        (sw, sx, sy, sv) = (sw + w, sx + w * v.x, sy + w * v.y, sv + w * v.value_dph);
    }
    if !positive(sw) {
        return None;
    }
    let (mx, my, mv) = (sx / sw, sy / sw, sv / sw);
    let (mut cxx, mut cxy, mut cyy, mut cxv, mut cyv) = (0.0f32, 0.0f32, 0.0f32, 0.0f32, 0.0f32);
    for (w, v) in nodes().filter(|(w, _)| *w > 0.0) {
        let (dx, dy, dv) = (v.x - mx, v.y - my, v.value_dph - mv);
        cxx += w * dx * dx;
        cxy += w * dx * dy;
        cyy += w * dy * dy;
        cxv += w * dx * dv;
        cyv += w * dy * dv;
    }
    let det = cxx * cyy - cxy * cxy;
    // `det / (cxx cyy) = 1 - rho^2`, rho the weighted correlation of x and y: at least 1e-2
    // (|rho| <= 0.995), else the positions lie too close to a line for a plane's second
    // slope (its f32 error grows as 1 / (1 - rho^2)).
    if !(det > MIN_SPAN * cxx * cyy && det.is_finite()) {
        return None;
    }
    let gradient = [(cyy * cxv - cxy * cyv) / det, (cxx * cyv - cxy * cxv) / det];
    gradient.iter().all(|g| g.is_finite()).then_some(gradient)
}

/// Least `1 - rho^2` of the weighted node positions for a plane fit (see `weighted_gradient`).
const MIN_SPAN: f32 = 1e-2;

/// The nearest hull edge or vertex of `(x, y)` by scanning every hull edge (the smallest f32
/// distance, ties to the lower index); for queries `hull::nearest_edge` cannot certify.
fn nearest_by_scan(mesh: &Mesh<'_>, x: f32, y: f32) -> Option<Nearest> {
    let n = mesh.hull_edge_count();
    let mut best: Option<(f32, Nearest)> = None;
    for h in 0..n {
        let Some((a, b)) = mesh.hull_edge_vertices(h) else { continue };
        let (d2, _) = edge_nearest(&a, &b, x, y);
        let e = sub([b.x, b.y], [a.x, a.y]);
        let along = dot(sub([x, y], [a.x, a.y]), e);
        let at = if !positive(along) {
            Nearest::Vertex(h)
        } else if along >= dot(e, e) {
            Nearest::Vertex(cyclic(h, 1, n))
        } else {
            Nearest::Edge(h)
        };
        if best.is_none_or(|(d, _)| d2 < d) {
            best = Some((d2, at));
        }
    }
    best.map(|(_, at)| at)
}
