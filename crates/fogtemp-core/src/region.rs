//! The calibrated region of an axis: a convex polygon in the normalised (T, dT/dt) plane
//! (the convex hull of the calibration points), and what the polynomial does outside it.
//!
//! A polynomial fitted over a region can run away outside it (a cooling run at rates no
//! calibration run had). With [`PolyOutside::HoldAtBoundary`] the polynomial is evaluated at
//! the point of the region's boundary nearest the query instead, as the mesh holds its hull
//! value, and the evaluation says `outside_hull` (the compensator flags `OUTSIDE_HULL`);
//! with [`PolyOutside::LinearFromBoundary`] it is continued by its tangent plane at that point.
//! Inside (or on) the region the polynomial is evaluated at the query itself, bit for bit as
//! without a region. Cost: at most [`MAX_REGION_VERTICES`] edge tests and projections.

use crate::wire::{f32_at, MAX_REGION_VERTICES, REGION_VERTEX_LEN};

/// What the polynomial of an axis does outside the calibrated region.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PolyOutside {
    /// Evaluated at the query wherever it is (version 1 behaviour). Blob code 0.
    Extrapolate,
    /// Evaluated at the nearest point of the region's boundary; flagged `OUTSIDE_HULL`.
    /// Blob code 1; needs a region.
    HoldAtBoundary,
    /// Continued linearly from the nearest point `q` of the region's boundary: `p(q) +
    /// grad p(q) . (x - q)` (the polynomial's tangent plane at `q`); flagged `OUTSIDE_HULL`.
    /// A dependence that is linear in the rate (a Shupe term) extrapolates exactly; the
    /// higher powers cannot run away (growth at most linear in the distance). Blob code 2;
    /// needs a region.
    LinearFromBoundary,
}

impl PolyOutside {
    /// The blob code of this policy.
    pub fn code(self) -> u32 {
        match self {
            PolyOutside::Extrapolate => 0,
            PolyOutside::HoldAtBoundary => 1,
            PolyOutside::LinearFromBoundary => 2,
        }
    }

    /// The policy with blob code `code`.
    pub fn from_code(code: u32) -> Option<Self> {
        match code {
            0 => Some(PolyOutside::Extrapolate),
            1 => Some(PolyOutside::HoldAtBoundary),
            2 => Some(PolyOutside::LinearFromBoundary),
            _ => None,
        }
    }
}

/// The calibrated region, borrowed from the blob (validated by `Model::from_bytes`: 3 to
/// [`MAX_REGION_VERTICES`] finite vertices, counter-clockwise, convex, going round once).
#[derive(Clone, Copy, Debug)]
pub struct Region<'a> {
    vertices: &'a [u8],
}

impl<'a> Region<'a> {
    pub(crate) fn new(vertices: &'a [u8]) -> Self {
        Self { vertices }
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> u32 {
        (self.vertices.len() / REGION_VERTEX_LEN).min(MAX_REGION_VERTICES as usize) as u32
    }

    /// Vertex `index` (normalised `(x, y)`), if present.
    pub fn vertex(&self, index: u32) -> Option<(f32, f32)> {
        let at = (index as usize).checked_mul(REGION_VERTEX_LEN)?;
        Some((f32_at(self.vertices, at)?, f32_at(self.vertices, at.checked_add(4)?)?))
    }

    /// The edges `(a, b)`, counter-clockwise, the last closing the polygon.
    fn edges(&self) -> impl Iterator<Item = ((f32, f32), (f32, f32))> + '_ {
        let n = self.vertex_count();
        (0..n).filter_map(move |i| Some((self.vertex(i)?, self.vertex((i + 1).checked_rem(n)?)?)))
    }

    /// `(x, y)` lies inside or on the boundary (left of or on every edge).
    pub fn contains(&self, x: f32, y: f32) -> bool {
        self.edges().all(|((ax, ay), (bx, by))| (bx - ax) * (y - ay) - (by - ay) * (x - ax) >= 0.0)
    }

    /// The point of the boundary nearest `(x, y)` (in the normalised plane), for a query
    /// outside the region. Chosen by where the query lies, not by comparing distances (which
    /// f32 cannot resolve far out): the foot on an edge whose line has the query outside and
    /// whose span contains its projection, else the vertex between an edge whose projection
    /// falls past its end and the next whose projection falls before its start (the
    /// Voronoi regions of a convex polygon's edges and vertices). The nearest of all edge
    /// projections as a fallback (rounding on a region boundary).
    pub fn nearest_boundary_point(&self, x: f32, y: f32) -> (f32, f32) {
        let n = self.vertex_count();
        let projection = |i: u32| -> Option<(f32, f32, f32, f32)> {
            let (a, b) = (self.vertex(i.checked_rem(n)?)?, self.vertex((i + 1).checked_rem(n)?)?);
            let (ex, ey) = (b.0 - a.0, b.1 - a.1);
            let len2 = ex * ex + ey * ey;
            let t = if len2 > 0.0 { ((x - a.0) * ex + (y - a.1) * ey) / len2 } else { 0.0 };
            let cross = ex * (y - a.1) - ey * (x - a.0);
            Some((t, cross, ex, ey))
        };
        let mut previous_t = projection(n.saturating_sub(1)).map_or(0.0, |p| p.0);
        let mut best = (f32::INFINITY, (x, y));
        for i in 0..n {
            let (Some((t, cross, ex, ey)), Some(a)) = (projection(i), self.vertex(i)) else { continue };
            if cross < 0.0 && (0.0..=1.0).contains(&t) {
                return (a.0 + t * ex, a.1 + t * ey);
            }
            if previous_t >= 1.0 && t <= 0.0 {
                return a;
            }
            previous_t = t;
            // Finite: |x|, |y| <= MAX_NORMALISED_COORD and the edge has a length (as in
            // `Mesh::nearest_hull_value`).
            let tc = t.clamp(0.0, 1.0);
            let (qx, qy) = (a.0 + tc * ex, a.1 + tc * ey);
            let d2 = (x - qx) * (x - qx) + (y - qy) * (y - qy);
            if d2 < best.0 {
                best = (d2, (qx, qy));
            }
        }
        best.1
    }
}
