//! The point of a mesh's convex hull nearest a query outside it, without scanning the hull.
//!
//! The hull (validated: counter-clockwise, convex up to f32 rounding) is searched with cross
//! and dot products only (no `atan2`, no allocation):
//!
//! 1. Facing edge, O(log n) ([`nearest_edge`], for `Mesh::nearest_hull_value`): the rays
//!    from an interior point `c` (the centroid of three hull vertices a third of the hull
//!    apart) through the hull vertices cut the plane into wedges, in counter-clockwise order.
//!    A binary search finds the wedge holding the query; the segment from `c` to an outside
//!    query leaves the hull through that wedge's edge.
//! 2. Descent: from that edge, step along the hull towards the query's projection (back
//!    while it falls before the edge's start, on while it falls past its end) until the
//!    query lies in the normal cone of an edge (projection on the edge, query on its outer
//!    side) or of a vertex (projection past the end of the edge before it and before the
//!    start of the edge after it). For a convex polygon that is the characterisation of the
//!    nearest point `q*`: `(p - q*) . (q - q*) <= 0` for every hull point `q`. The answer is
//!    chosen by where the query lies, as `Region::nearest_boundary_point` does, not by
//!    comparing distances over the whole hull, which f32 cannot resolve far out.
//! 3. Value, by the certificate: on an edge, that edge's value at the projection; at a vertex,
//!    the scan's choice between the two edges meeting there (both give the vertex up to
//!    rounding: the smaller f32 distance, on a tie the lower hull index), with the scan's own
//!    arithmetic. So the value is the scan's bit for bit except where the scan's f32 distances
//!    let another edge win by rounding (a tie).
//!
//! A query that a walk took out of the mesh needs no step 1: the walk crossed a hull edge, and
//! [`value_from_slot`] checks the same certificate on that edge and at its two ends, finding
//! the neighbouring hull edges through the triangles around the end vertex (the blob has no
//! map from a triangle to its hull index, and the format is a contract).
//!
//! Anything not certified (non-finite query, fewer than 3 edges, a degenerate fan, a zero
//! length edge, rounding that puts the query on the inner side of its edge, no certificate
//! within `n` steps) returns `None`, and the caller searches (step 1) or scans every edge.

use crate::mesh::{edge_nearest, Mesh, Vertex};
use crate::wire::NO_NEIGHBOUR;

/// A point or a vector of the normalised plane.
pub(crate) type P = [f32; 2];

/// Where the nearest hull point of a query lies, by hull edge index. The certificates are
/// disjoint also where f32 puts a query exactly on the boundary of two (a projection exactly
/// at an edge's end counts as the vertex), so every path that certifies agrees.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Nearest {
    /// On edge `h` (its projection parameter in `(0, 1)`, the query on its outer side).
    Edge(u32),
    /// At the start vertex of edge `h` (projection parameter at least 1 on edge `h - 1`, at most
    /// 0 on edge `h`).
    Vertex(u32),
}

impl Nearest {
    /// The edge holding the point (on it, or at its start).
    pub(crate) fn edge(self) -> u32 {
        match self {
            Nearest::Edge(h) | Nearest::Vertex(h) => h,
        }
    }
}

/// The hull edge or vertex whose normal cone holds `(x, y)`, or `None` when that cannot be
/// certified (see the module documentation).
pub(crate) fn nearest_edge(mesh: &Mesh<'_>, x: f32, y: f32) -> Option<Nearest> {
    if !(x.is_finite() && y.is_finite()) {
        return None;
    }
    let n = mesh.hull_edge_count();
    if n < 3 {
        return None;
    }
    let at = |h: u32| mesh.hull_start(h);
    let facing = facing_edge(&at, n, [x, y])?;
    descend(&at, n, facing, [x, y])
}

/// `h + step` modulo `n` (`h < n`, `n > 0`, `|step| <= 1`).
#[inline(always)]
pub(crate) fn cyclic(h: u32, step: i32, n: u32) -> u32 {
    match step {
        s if s < 0 => h.checked_sub(1).unwrap_or(n.saturating_sub(1)),
        0 => h,
        _ => h.checked_add(1).filter(|&next| next < n).unwrap_or(0),
    }
}

/// The edge of the fan wedge around an interior point that holds `p`: the largest `h` whose
/// start vertex's direction comes no later than `p`'s, counter-clockwise from vertex 0's.
fn facing_edge(at: &impl Fn(u32) -> Option<P>, n: u32, p: P) -> Option<u32> {
    let (a, b, c) = (at(0)?, at(n / 3)?, at(n - n / 3)?);
    // Three hull vertices in counter-clockwise order; their centroid is interior unless
    // they are (nearly) collinear.
    if !positive(cross(sub(b, a), sub(c, a))) {
        return None;
    }
    let centre = [(a[0] + b[0] + c[0]) / 3.0, (a[1] + b[1] + c[1]) / 3.0];
    let (d0, w) = (sub(a, centre), sub(p, centre));
    let (mut lo, mut hi) = (0u32, n);
    while hi - lo > 1 {
        let mid = lo + (hi - lo) / 2;
        if no_later(d0, sub(at(mid)?, centre), w) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    Some(lo)
}

/// Whether direction `u` comes no later than direction `w`, both measured counter-clockwise
/// from `d0` in `[0, 2 pi)`: first by half-plane, then (less than half a turn apart) by the
/// sign of their cross product.
#[inline(always)]
fn no_later(d0: P, u: P, w: P) -> bool {
    match (first_half(d0, u), first_half(d0, w)) {
        (true, false) => true,
        (false, true) => false,
        _ => cross(u, w) >= 0.0,
    }
}

/// Direction `u` lies in `[0, pi)` counter-clockwise from `d0`.
#[inline(always)]
fn first_half(d0: P, u: P) -> bool {
    let c = cross(d0, u);
    c > 0.0 || (c == 0.0 && dot(d0, u) > 0.0)
}

/// From edge `start`, the edge (or the edge starting at the vertex) whose normal cone holds
/// `p`, stepping one way only; `None` without a certificate.
fn descend(at: &impl Fn(u32) -> Option<P>, n: u32, start: u32, p: P) -> Option<Nearest> {
    let mut h = start;
    let mut direction = 0i32;
    for _ in 0..n {
        let (a, b) = (at(h)?, at(cyclic(h, 1, n))?);
        let (e, ap) = (sub(b, a), sub(p, a));
        let len2 = dot(e, e);
        if !positive(len2) {
            return None;
        }
        let along = dot(ap, e);
        if along <= 0.0 {
            // Before the start of h: coming from h + 1 (past its end), vertex a is the answer.
            if direction > 0 {
                return Some(Nearest::Vertex(h));
            }
            (direction, h) = (-1, cyclic(h, -1, n));
        } else if along >= len2 {
            if direction < 0 {
                return Some(Nearest::Vertex(cyclic(h, 1, n)));
            }
            (direction, h) = (1, cyclic(h, 1, n));
        } else {
            // The projection falls on h: the answer if p is on its outer (right) side.
            return (cross(e, ap) <= 0.0).then_some(Nearest::Edge(h));
        }
    }
    None
}

/// `v > 0` (false for NaN).
#[inline(always)]
pub(crate) fn positive(v: f32) -> bool {
    v > 0.0
}

#[inline(always)]
pub(crate) fn sub(a: P, b: P) -> P {
    [a[0] - b[0], a[1] - b[1]]
}

#[inline(always)]
pub(crate) fn dot(a: P, b: P) -> f32 {
    a[0] * b[0] + a[1] * b[1]
}

#[inline(always)]
fn cross(a: P, b: P) -> f32 {
    a[0] * b[1] - a[1] * b[0]
}

/// Most triangles around one hull vertex visited to find the next or previous hull edge; a
/// vertex with more (possible, not met on a writer's mesh) falls back to the search.
const MAX_FAN: u32 = 64;

/// A hull edge named by its triangle slot: edge `k` of triangle `t` (from its vertex `k + 1`
/// to `k + 2`, neighbour [`NO_NEIGHBOUR`]), with the indices of its ends.
#[derive(Clone, Copy)]
struct Slot {
    t: u32,
    from: u32,
    to: u32,
}

/// Edge `k` of triangle `t` if it is a hull edge.
fn slot(mesh: &Mesh<'_>, t: u32, k: usize) -> Option<Slot> {
    let (vs, nb) = mesh.corners(t)?;
    if *nb.get(k)? != NO_NEIGHBOUR {
        return None;
    }
    Some(Slot { t, from: *vs.get((k + 1) % 3)?, to: *vs.get((k + 2) % 3)? })
}

/// Position of vertex `v` in a triangle's vertex list.
#[inline(always)]
fn position(vs: [u32; 3], v: u32) -> Option<usize> {
    vs.iter().position(|&w| w == v)
}

/// The hull edge after `s`: the triangles around its end vertex, turning clockwise from `s`'s
/// triangle, up to the one whose edge starting at that vertex is on the hull.
fn next_slot(mesh: &Mesh<'_>, s: Slot) -> Option<Slot> {
    let pivot = s.to;
    let mut t = s.t;
    for _ in 0..MAX_FAN {
        let (vs, nb) = mesh.corners(t)?;
        // Edge j + 2 runs from vertex j (the pivot) to j + 1.
        let j = position(vs, pivot)?;
        let m = (j + 2) % 3;
        match *nb.get(m)? {
            NO_NEIGHBOUR => return Some(Slot { t, from: pivot, to: *vs.get((j + 1) % 3)? }),
            n => t = n,
        }
    }
    None
}

/// The hull edge before `s`: as [`next_slot`], around `s`'s start vertex, counter-clockwise.
fn prev_slot(mesh: &Mesh<'_>, s: Slot) -> Option<Slot> {
    let pivot = s.from;
    let mut t = s.t;
    for _ in 0..MAX_FAN {
        let (vs, nb) = mesh.corners(t)?;
        // Edge i + 1 runs from vertex i + 2 to i (the pivot).
        let i = position(vs, pivot)?;
        let m = (i + 1) % 3;
        match *nb.get(m)? {
            NO_NEIGHBOUR => return Some(Slot { t, from: *vs.get((i + 2) % 3)?, to: pivot }),
            n => t = n,
        }
    }
    None
}

/// `(along, len2, cross)` of `p` relative to the edge from `a` to `b`, with the arithmetic of
/// [`descend`]: the projection parameter is `along / len2`.
#[inline(always)]
fn edge_frame(a: &Vertex, b: &Vertex, p: P) -> (f32, f32, f32) {
    let (e, ap) = (sub([b.x, b.y], [a.x, a.y]), sub(p, [a.x, a.y]));
    (dot(ap, e), dot(e, e), cross(e, ap))
}

/// Most hull edges [`value_from_slot`] steps along before it leaves the query to the search.
const MAX_HULL_STEPS: u32 = 16;

/// The value at the nearest hull point of `p`, starting from the hull edge `k` of triangle
/// `t` (the edge a walk crossed to leave the mesh): the descent of [`descend`], stepping from
/// one hull edge to the next through the triangles around their shared vertex, and the value
/// as `Mesh::nearest_hull_value` takes it. `None` without a certificate within
/// [`MAX_HULL_STEPS`] edges.
pub(crate) fn value_from_slot(mesh: &Mesh<'_>, t: u32, k: usize, x: f32, y: f32) -> Option<f32> {
    if !(x.is_finite() && y.is_finite()) || mesh.hull_edge_count() < 3 {
        return None;
    }
    let p = [x, y];
    let mut current = slot(mesh, t, k)?;
    // The edge visited before `current` and the direction of the step (+1 on, -1 back).
    let mut came: Option<(Slot, i32)> = None;
    for _ in 0..MAX_HULL_STEPS {
        let (a, b) = (mesh.vertex(current.from)?, mesh.vertex(current.to)?);
        let (along, len2, side) = edge_frame(&a, &b, p);
        if !positive(len2) {
            return None;
        }
        if along <= 0.0 {
            if let Some((last, 1)) = came {
                // Past the end of `last`, before the start of `current`: their shared vertex.
                let before = mesh.vertex(last.from)?;
                let first = mesh.hull_start_index(0)? == current.from;
                return Some(vertex_value((&before, &a), (&a, &b), first, x, y));
            }
            (came, current) = (Some((current, -1)), prev_slot(mesh, current)?);
        } else if along >= len2 {
            if let Some((last, -1)) = came {
                let after = mesh.vertex(last.to)?;
                let first = mesh.hull_start_index(0)? == last.from;
                return Some(vertex_value((&a, &b), (&b, &after), first, x, y));
            }
            (came, current) = (Some((current, 1)), next_slot(mesh, current)?);
        } else {
            return (side <= 0.0).then(|| edge_nearest(&a, &b, x, y).1);
        }
    }
    None
}

/// The value at the nearest hull point of `p` when it lies on the hull edge `k` of triangle `t`
/// itself (the edge a walk crossed; most outside queries of a fine mesh): the first step of
/// [`value_from_slot`] with its arithmetic, so `Some` only where [`value_from_slot`] returns the
/// same value on that step; `None` for anything else (the projection off the edge, the query
/// on its inner side, a degenerate edge), which [`value_from_slot`] then decides. Reads the one
/// record and the edge's two vertices, without the descent's bookkeeping.
#[inline]
pub(crate) fn value_on_crossed_edge(mesh: &Mesh<'_>, t: u32, k: usize, x: f32, y: f32) -> Option<f32> {
    if !(x.is_finite() && y.is_finite()) || mesh.hull_edge_count() < 3 {
        return None;
    }
    let edge = slot(mesh, t, k)?;
    let (a, b) = (mesh.vertex(edge.from)?, mesh.vertex(edge.to)?);
    let (along, len2, side) = edge_frame(&a, &b, [x, y]);
    let on_edge = positive(len2) && along > 0.0 && along < len2 && side <= 0.0;
    on_edge.then(|| edge_nearest(&a, &b, x, y).1)
}

/// The nearest hull point of `(x, y)` when it lies on the hull edge `k` of triangle `t` itself
/// (the edge a walk crossed), by [`value_on_crossed_edge`]'s certificate: the edge's start and
/// end vertex indices, the projection parameter `s`, the point and the value there (as
/// `src/beyond.rs` computes them for a certified edge, so the same bits); `None` where that
/// certificate does not hold.
#[inline]
pub(crate) fn foot_on_crossed_edge(
    mesh: &Mesh<'_>,
    t: u32,
    k: usize,
    x: f32,
    y: f32,
) -> Option<(u32, u32, f32, P, f32)> {
    if !(x.is_finite() && y.is_finite()) || mesh.hull_edge_count() < 3 {
        return None;
    }
    let edge = slot(mesh, t, k)?;
    let (a, b) = (mesh.vertex(edge.from)?, mesh.vertex(edge.to)?);
    let (along, len2, side) = edge_frame(&a, &b, [x, y]);
    if !(positive(len2) && along > 0.0 && along < len2 && side <= 0.0) {
        return None;
    }
    let e = sub([b.x, b.y], [a.x, a.y]);
    let s = (dot(sub([x, y], [a.x, a.y]), e) / len2).clamp(0.0, 1.0);
    Some((edge.from, edge.to, s, [a.x + s * e[0], a.y + s * e[1]], edge_nearest(&a, &b, x, y).1))
}

/// The value at the vertex between hull edges `before` (ending there) and `after` (starting
/// there): the scan's choice between the two (the smaller f32 squared distance; on a tie the
/// lower hull index, which is `before` unless `after` is hull edge 0). Each gives the vertex up
/// to rounding; taking it as the scan does keeps the value the scan's bit for bit.
pub(crate) fn vertex_value(
    before: (&Vertex, &Vertex),
    after: (&Vertex, &Vertex),
    after_is_first: bool,
    x: f32,
    y: f32,
) -> f32 {
    let (b, a) = (edge_nearest(before.0, before.1, x, y), edge_nearest(after.0, after.1, x, y));
    let (low, high) = if after_is_first { (a, b) } else { (b, a) };
    if high.0 < low.0 {
        high.1
    } else {
        low.1
    }
}
