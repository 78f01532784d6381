//! The hull edge nearest a query outside a mesh's convex hull, without scanning the hull.
//!
//! The hull (validated: counter-clockwise, convex up to f32 rounding) is searched in two
//! steps, with cross and dot products only (no `atan2`, no division, no allocation):
//!
//! 1. Facing edge, O(log n): the rays from an interior point `c` (the centroid of three hull
//!    vertices a third of the hull apart) through the hull vertices cut the plane into
//!    wedges, in counter-clockwise order. A binary search finds the wedge holding the query;
//!    the segment from `c` to an outside query leaves the hull through that wedge's edge.
//! 2. Descent: from that edge, step along the hull towards the query's projection (back
//!    while it falls before the edge's start, on while it falls past its end) until the
//!    query lies in the normal cone of an edge (projection on the edge, query on its outer
//!    side) or of a vertex (projection past the end of the edge before it and before the
//!    start of the edge after it). For a convex polygon that is the characterisation of the
//!    nearest point `q*`: `(p - q*) . (q - q*) <= 0` for every hull point `q`. The answer is
//!    chosen by where the query lies, as `Region::nearest_boundary_point` does, not by
//!    comparing distances that f32 cannot resolve far out.
//!
//! Anything not certified (non-finite query, fewer than 3 edges, a degenerate fan, a zero
//! length edge, rounding that puts the query on the inner side of its edge, no certificate
//! within `n` steps) returns `None`, and the caller scans every edge instead.

use crate::mesh::Mesh;

/// A point or a vector of the normalised plane.
type P = [f32; 2];

/// The hull edge whose normal cone (with that of its start vertex) holds `(x, y)`, or `None`
/// when that cannot be certified (see the module documentation).
pub(crate) fn nearest_edge(mesh: &Mesh<'_>, x: f32, y: f32) -> Option<u32> {
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
fn descend(at: &impl Fn(u32) -> Option<P>, n: u32, start: u32, p: P) -> Option<u32> {
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
        if along < 0.0 {
            // Before the start of h: coming from h + 1 (past its end), vertex a is the answer.
            if direction > 0 {
                return Some(h);
            }
            (direction, h) = (-1, cyclic(h, -1, n));
        } else if along > len2 {
            if direction < 0 {
                return Some(cyclic(h, 1, n));
            }
            (direction, h) = (1, cyclic(h, 1, n));
        } else {
            // The projection falls on h: the answer if p is on its outer (right) side.
            return (cross(e, ap) <= 0.0).then_some(h);
        }
    }
    None
}

/// `v > 0` (false for NaN).
#[inline(always)]
fn positive(v: f32) -> bool {
    v > 0.0
}

#[inline(always)]
fn sub(a: P, b: P) -> P {
    [a[0] - b[0], a[1] - b[1]]
}

#[inline(always)]
fn dot(a: P, b: P) -> f32 {
    a[0] * b[0] + a[1] * b[1]
}

#[inline(always)]
fn cross(a: P, b: P) -> f32 {
    a[0] * b[1] - a[1] * b[0]
}
