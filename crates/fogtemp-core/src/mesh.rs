//! Triangle mesh with linear (barycentric) interpolation: the paper's eq. 13-19.
//!
//! Points live in the normalised plane `(x, y)`. Each triangle record carries its
//! barycentric transform and its value plane, precomputed by the writer in f64, so
//! locating and interpolating costs two affine evaluations per visited triangle.

use crate::error::Error;
use crate::wire::{
    self, HULL_EDGE_LEN, NO_NEIGHBOUR, TRIANGLE_LEN, TRI_BARY, TRI_NEIGHBOURS, TRI_ORIGIN, TRI_PLANE,
    TRI_VERTICES, VERTEX_LEN,
};

/// A query counts as inside a triangle when every barycentric coordinate is at
/// least `-INSIDE_EPS` (absorbs f32 rounding on shared edges).
pub const INSIDE_EPS: f32 = 1e-6;

/// What to return for a query outside the convex hull of the mesh.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OutsidePolicy {
    /// The value at the nearest point of the hull (in the normalised plane), so the
    /// output is continuous across the hull. Blob code 0; the default.
    NearestHull,
    /// Zero: the mesh contributes nothing outside (hybrid models fall back to the
    /// polynomial). Blob code 1.
    Zero,
    /// The value at the nearest hull point `q` continued linearly to the query, with the
    /// gradient of the weighted least-squares plane of the nodes within
    /// [`crate::GRADIENT_RADIUS`] of `q` (`src/beyond.rs`): the mesh's first-order
    /// continuation, as the polynomial's `PolyOutside::LinearFromBoundary`. Continuous
    /// across the hull, exact for a plane. Blob code 2 (a reader that knows only 0 and 1
    /// refuses the blob). One pass over every node per outside query.
    LinearFromBoundary,
    /// As [`OutsidePolicy::LinearFromBoundary`], with the gradient stored in the blob: the
    /// writer's least-squares gradient at each hull vertex (the same biweight neighbourhood),
    /// linear along each hull edge between its two vertices' (`src/beyond.rs`). An outside
    /// query costs the nearest hull point and O(1), no pass over the nodes. Blob code 3,
    /// format version 3 (the gradients follow the region).
    StoredGradients,
}

impl OutsidePolicy {
    /// The blob code of this policy.
    pub fn code(self) -> u32 {
        match self {
            OutsidePolicy::NearestHull => 0,
            OutsidePolicy::Zero => 1,
            OutsidePolicy::LinearFromBoundary => 2,
            OutsidePolicy::StoredGradients => 3,
        }
    }

    /// The policy with blob code `code`.
    pub fn from_code(code: u32) -> Option<Self> {
        match code {
            0 => Some(OutsidePolicy::NearestHull),
            1 => Some(OutsidePolicy::Zero),
            2 => Some(OutsidePolicy::LinearFromBoundary),
            3 => Some(OutsidePolicy::StoredGradients),
            _ => None,
        }
    }
}

/// The caller-owned walk state: the triangle the last query ended in.
///
/// Any value is safe: a stale hint or one from another mesh is clamped to a valid
/// triangle, and a failed call leaves it unchanged.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct WalkHint(pub u32);

/// Where a query point lies.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Location {
    /// Inside (or on the boundary of) `triangle`, with barycentric coordinates
    /// `bary[k]` for the triangle's vertex `k`.
    Inside {
        /// Triangle index.
        triangle: u32,
        /// Barycentric coordinates, summing to 1.
        bary: [f32; 3],
    },
    /// Outside the convex hull; `triangle` is the hull triangle where the walk stopped.
    Outside {
        /// Triangle index.
        triangle: u32,
    },
}

/// A mesh value with its provenance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MeshValue {
    /// Interpolated value, deg/h.
    pub value_dph: f32,
    /// Triangle that produced it (inside) or where the walk left the hull (outside).
    pub triangle: u32,
    /// The query was outside the hull and the outside policy produced the value.
    pub outside_hull: bool,
}

/// One triangle record as stored in the blob.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleRecord {
    /// Origin of the transforms: the position of vertex 2.
    pub origin: [f32; 2],
    /// Barycentric transform: `l0 = b0 dx + b1 dy`, `l1 = b2 dx + b3 dy`, `l2 = 1 - l0 - l1`,
    /// with `(dx, dy)` the query minus `origin`.
    pub bary: [f32; 4],
    /// Value plane: `value = p0 dx + p1 dy + p2`.
    pub plane: [f32; 3],
    /// Neighbour across the edge opposite vertex k, or [`NO_NEIGHBOUR`] on the hull.
    pub neighbours: [u32; 3],
    /// Vertex indices, counter-clockwise.
    pub vertices: [u32; 3],
}

/// One mesh vertex: normalised position and value.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Vertex {
    /// Normalised temperature.
    pub x: f32,
    /// Normalised rate.
    pub y: f32,
    /// Bias at this node, deg/h.
    pub value_dph: f32,
}

/// The mesh part of an axis, borrowed from the blob (validated by `Model::from_bytes`).
#[derive(Clone, Copy, Debug)]
pub struct Mesh<'a> {
    pub(crate) vertices: &'a [u8],
    pub(crate) triangles: &'a [u8],
    pub(crate) hull: &'a [u8],
    /// Hull gradients ([`wire::HULL_GRADIENT_LEN`] each), one per hull edge with
    /// [`OutsidePolicy::StoredGradients`], else empty.
    pub(crate) gradients: &'a [u8],
    pub(crate) policy: OutsidePolicy,
    /// The axis this mesh belongs to (named in errors).
    pub(crate) axis: u16,
}

impl<'a> Mesh<'a> {
    /// Number of vertices.
    pub fn vertex_count(&self) -> u32 {
        (self.vertices.len() / VERTEX_LEN) as u32
    }

    /// Number of triangles.
    pub fn triangle_count(&self) -> u32 {
        (self.triangles.len() / TRIANGLE_LEN) as u32
    }

    /// Number of hull edges.
    pub fn hull_edge_count(&self) -> u32 {
        (self.hull.len() / HULL_EDGE_LEN) as u32
    }

    /// The outside-hull policy stored in the blob.
    pub fn outside_policy(&self) -> OutsidePolicy {
        self.policy
    }

    /// The stored continuation gradient `[d/dx, d/dy]` (deg/h per normalised unit) at hull
    /// vertex `index`: the start of hull edge `index`, which with this policy is also vertex
    /// `index` (the writer numbers the hull vertices first, validated). `None` unless the
    /// policy is [`OutsidePolicy::StoredGradients`] and the hull vertex exists.
    pub fn hull_gradient(&self, index: u32) -> Option<[f32; 2]> {
        let start = (index as usize).checked_mul(wire::HULL_GRADIENT_LEN)?;
        let g = wire::array::<{ wire::HULL_GRADIENT_LEN }>(self.gradients, start)?;
        Some([wire::f32_at(&g, 0)?, wire::f32_at(&g, 4)?])
    }

    /// Vertex `index`, if it exists.
    pub fn vertex(&self, index: u32) -> Option<Vertex> {
        let start = (index as usize).checked_mul(VERTEX_LEN)?;
        let v = wire::array::<VERTEX_LEN>(self.vertices, start)?;
        Some(Vertex { x: wire::f32_at(&v, 0)?, y: wire::f32_at(&v, 4)?, value_dph: wire::f32_at(&v, 8)? })
    }

    /// Triangle record `index`, if it exists.
    #[inline]
    pub fn triangle(&self, index: u32) -> Option<TriangleRecord> {
        let start = (index as usize).checked_mul(TRIANGLE_LEN)?;
        let r = wire::array::<TRIANGLE_LEN>(self.triangles, start)?;
        let f = |o: usize| wire::f32_at(&r, o).unwrap_or(f32::NAN);
        let u = |o: usize| wire::u32_at(&r, o).unwrap_or(NO_NEIGHBOUR);
        Some(TriangleRecord {
            origin: [f(0), f(4)],
            bary: [f(8), f(12), f(16), f(20)],
            plane: [f(24), f(28), f(32)],
            neighbours: [u(36), u(40), u(44)],
            vertices: [u(48), u(52), u(56)],
        })
    }

    /// Hull edge `index` as `(triangle, edge)`; edge k runs from vertex k+1 to k+2.
    pub fn hull_edge(&self, index: u32) -> Option<(u32, u32)> {
        let start = (index as usize).checked_mul(HULL_EDGE_LEN)?;
        Some((wire::u32_at(self.hull, start)?, wire::u32_at(self.hull, start.checked_add(4)?)?))
    }

    /// The 60-byte record of triangle `t`.
    #[inline(always)]
    fn record(&self, t: u32) -> Option<&'a [u8; TRIANGLE_LEN]> {
        let start = (t as usize).checked_mul(TRIANGLE_LEN)?;
        // One bounds check: `start + TRIANGLE_LEN <= len` (neither add overflows where
        // `usize` is 64 bits wide, so the compiler drops those checks there).
        self.triangles.get(start..start.checked_add(TRIANGLE_LEN)?)?.first_chunk::<TRIANGLE_LEN>()
    }

    /// The visibility walk from triangle `t` (see [`Mesh::locate`]), reading per step only
    /// the origin and the transform, and one neighbour when it moves on. `None` when the
    /// walk does not settle within `max_steps`. `previous` is the triangle the walk came
    /// from ([`NO_NEIGHBOUR`] for a fresh walk).
    #[inline(always)]
    fn walk(&self, mut previous: u32, mut t: u32, x: f32, y: f32, max_steps: u32) -> Option<WalkEnd<'a>> {
        for _ in 0..=max_steps {
            let r = self.record(t)?;
            let (dx, dy) = (x - rec_f32(r, TRI_ORIGIN.start), y - rec_f32(r, TRI_ORIGIN.start + 4));
            let b = TRI_BARY.start;
            let l0 = rec_f32(r, b) * dx + rec_f32(r, b + 4) * dy;
            let l1 = rec_f32(r, b + 8) * dx + rec_f32(r, b + 12) * dy;
            let bary = [l0, l1, 1.0 - l0 - l1];
            let (k, lmin) = most_negative(bary);
            if lmin >= -INSIDE_EPS {
                return Some(WalkEnd { triangle: t, record: r, delta: (dx, dy), bary, inside: true });
            }
            let next = rec_u32(r, TRI_NEIGHBOURS.start + 4 * k);
            // Stepping straight back means both triangles see the point beyond their
            // shared edge: only rounding does that, so the point is on the edge.
            if next == previous && next != NO_NEIGHBOUR {
                return Some(WalkEnd { triangle: t, record: r, delta: (dx, dy), bary, inside: true });
            }
            if next == NO_NEIGHBOUR {
                return Some(WalkEnd { triangle: t, record: r, delta: (dx, dy), bary, inside: false });
            }
            (previous, t) = (t, next);
        }
        None
    }

    /// Walks from `hint` (clamped), falling back to a full scan if the walk does not settle.
    #[inline(always)]
    fn walk_or_scan(&self, x: f32, y: f32, start: u32) -> Option<WalkEnd<'a>> {
        match self.walk(NO_NEIGHBOUR, start, x, y, self.triangle_count()) {
            Some(end) => Some(end),
            None => self.scan_end(x, y),
        }
    }

    /// The fallback when a walk does not settle: a full scan. Kept out of line so the walk's
    /// hot loop stays small.
    #[cold]
    #[inline(never)]
    fn scan_end(&self, x: f32, y: f32) -> Option<WalkEnd<'a>> {
        let (triangle, inside) = match self.locate_by_scan(x, y) {
            Location::Inside { triangle, .. } => (triangle, true),
            Location::Outside { triangle } => (triangle, false),
        };
        let record = self.record(triangle)?;
        let delta = (x - rec_f32(record, TRI_ORIGIN.start), y - rec_f32(record, TRI_ORIGIN.start + 4));
        let bary = barycentric_rec(record, x, y);
        Some(WalkEnd { triangle, record, delta, bary, inside })
    }

    /// Locates `(x, y)` by a visibility walk from `hint`: at each triangle, step across
    /// the edge with the most negative barycentric coordinate. Crossing a hull edge
    /// means the point is outside the (convex) hull. The walk is bounded by the
    /// triangle count; should it not settle (near-degenerate input), a full scan decides.
    ///
    /// On success `hint` is set to the triangle found.
    ///
    /// # Errors
    /// [`Error::NonFiniteSample`] for a NaN or infinite coordinate; hint unchanged.
    #[inline]
    pub fn locate(&self, x: f32, y: f32, hint: &mut WalkHint) -> Result<Location, Error> {
        let end = self.walk_from_hint(x, y, hint)?;
        Ok(if end.inside {
            Location::Inside { triangle: end.triangle, bary: end.bary }
        } else {
            Location::Outside { triangle: end.triangle }
        })
    }

    /// Locates by testing every triangle: the reference the walk must agree with,
    /// and its fallback. O(triangles).
    pub fn locate_by_scan(&self, x: f32, y: f32) -> Location {
        let mut best: Option<(u32, [f32; 3], f32)> = None;
        for t in 0..self.triangle_count() {
            let Some(rec) = self.triangle(t) else { break };
            let bary = barycentric(&rec, x, y);
            let (_, lmin) = most_negative(bary);
            if best.is_none_or(|(_, _, b)| lmin > b) {
                best = Some((t, bary, lmin));
            }
        }
        match best {
            Some((triangle, bary, lmin)) if lmin >= -INSIDE_EPS => Location::Inside { triangle, bary },
            Some((triangle, _, _)) => Location::Outside { triangle },
            None => Location::Outside { triangle: 0 },
        }
    }

    /// Interpolated value at `(x, y)`: the plane of the containing triangle, or the
    /// outside policy's value beyond the hull.
    ///
    /// # Errors
    /// [`Error::NonFiniteSample`] for a NaN or infinite coordinate; hint unchanged.
    #[inline]
    pub fn interpolate(&self, x: f32, y: f32, hint: &mut WalkHint) -> Result<MeshValue, Error> {
        match self.hint_test(x, y, hint.0) {
            Some(test) if test.inside & test.value.value_dph.is_finite() => Ok(test.value),
            _ => self.interpolate_walk(x, y, hint),
        }
    }

    /// The hot path of [`Mesh::interpolate`] and [`Mesh::interpolate_with_grid`]: whether
    /// the query lies inside the hint triangle `t` itself (about 999 of 1000 samples of a
    /// 1 kHz stream), and the plane of `t` there; `None` for a hint past the last triangle.
    ///
    /// When `inside` holds and the value is finite, the value is the answer, bit for bit:
    /// the general path tests `t` first with the same arithmetic, stops there, and leaves
    /// the hint at `t`. No separate finiteness check of the query is needed for that: a
    /// finite value implies a finite query. `dx = x - ox` is NaN or infinite when `x` is,
    /// and then so is `p0 dx + p1 dy + p2` for any `p0`, `p1`, `p2` (`0 * inf` is NaN, and
    /// NaN or infinity absorbs any addend). Every other outcome goes to the general path,
    /// which checks the query.
    #[inline(always)]
    fn hint_test(&self, x: f32, y: f32, t: u32) -> Option<HintTest<'a>> {
        let r = self.record(t)?;
        let (dx, dy) = (x - rec_f32(r, TRI_ORIGIN.start), y - rec_f32(r, TRI_ORIGIN.start + 4));
        let b = TRI_BARY.start;
        let l0 = rec_f32(r, b) * dx + rec_f32(r, b + 4) * dy;
        let l1 = rec_f32(r, b + 8) * dx + rec_f32(r, b + 12) * dy;
        let (exit, lmin) = most_negative([l0, l1, 1.0 - l0 - l1]);
        let p = TRI_PLANE.start;
        let value_dph = rec_f32(r, p) * dx + rec_f32(r, p + 4) * dy + rec_f32(r, p + 8);
        Some(HintTest {
            inside: lmin >= -INSIDE_EPS,
            value: MeshValue { value_dph, triangle: t, outside_hull: false },
            record: r,
            exit,
        })
    }

    /// The value at a query that [`Mesh::hint_test`] found start triangle `t` not to hold:
    /// what [`Mesh::walk_or_scan`] from `t` and [`Mesh::value_at`] give, without testing `t`
    /// again. The walk's first step with the
    /// test's own numbers: across the edge of the most negative coordinate into the neighbour,
    /// or, when that is a hull edge, out of the mesh there (most outside queries), straight to
    /// the outside policy.
    #[inline(always)]
    fn value_past(
        &self,
        t: u32,
        test: &HintTest<'a>,
        x: f32,
        y: f32,
        hint: &mut WalkHint,
    ) -> Option<MeshValue> {
        let next = rec_u32(test.record, TRI_NEIGHBOURS.start + 4 * test.exit);
        if next == NO_NEIGHBOUR {
            hint.0 = t;
            return Some(self.outside_value(t, test.exit, x, y));
        }
        let end = match self.walk(t, next, x, y, self.triangle_count().saturating_sub(1)) {
            Some(end) => end,
            None => self.scan_end(x, y)?,
        };
        hint.0 = end.triangle;
        Some(self.value_at(&end, x, y))
    }

    /// The general path of [`Mesh::interpolate`]: checks, walks, moves the hint. Out of line,
    /// so the hot path stays a handful of instructions; a walk that leaves the hint triangle
    /// costs far more than the call.
    #[inline(never)]
    fn interpolate_walk(&self, x: f32, y: f32, hint: &mut WalkHint) -> Result<MeshValue, Error> {
        let end = self.walk_from_hint(x, y, hint)?;
        Ok(self.value_at(&end, x, y))
    }

    /// Checks the query, walks from the (clamped) hint and, on success, moves the hint to
    /// the triangle found.
    #[inline(always)]
    fn walk_from_hint(&self, x: f32, y: f32, hint: &mut WalkHint) -> Result<WalkEnd<'a>, Error> {
        if !(x.is_finite() && y.is_finite()) {
            return Err(Error::NonFiniteSample);
        }
        let start = if hint.0 < self.triangle_count() { hint.0 } else { 0 };
        let end = self.walk_or_scan(x, y, start).ok_or(Error::BadMesh {
            check: "walk",
            axis: self.axis,
            index: start,
        })?;
        hint.0 = end.triangle;
        Ok(end)
    }

    /// Like [`Mesh::interpolate`], but located from the query's cell of `grid` (its triangle
    /// tested first, then a walk from it) instead of from the hint, which is moved to the
    /// triangle found: random-order queries cost a test or a few steps instead of
    /// O(sqrt(triangles)).
    ///
    /// # Errors
    /// [`Error::NonFiniteSample`] for a NaN or infinite coordinate; hint unchanged.
    #[inline]
    pub fn interpolate_with_grid(
        &self,
        x: f32,
        y: f32,
        hint: &mut WalkHint,
        grid: &StartGrid<'_>,
    ) -> Result<MeshValue, Error> {
        // The query's grid cell first, not the hint: with a few cells per triangle the cell's
        // triangle holds the query about as often as the hint of an ordered stream does, and
        // random-order queries (what a grid is for) skip a failed hint test.
        let start = self.grid_cell_triangle(grid, x, y);
        match self.hint_test(x, y, start) {
            Some(test) if test.inside & test.value.value_dph.is_finite() => {
                hint.0 = start;
                Ok(test.value)
            }
            Some(test) if !test.inside && x.is_finite() && y.is_finite() => self
                .value_past(start, &test, x, y, hint)
                .ok_or(Error::BadMesh { check: "walk", axis: self.axis, index: start }),
            _ => self.interpolate_grid_general(x, y, hint, grid),
        }
    }

    /// The start triangle of `(x, y)`'s grid cell, never past this mesh's last triangle
    /// whatever the grid's cells hold.
    #[inline(always)]
    fn grid_cell_triangle(&self, grid: &StartGrid<'_>, x: f32, y: f32) -> u32 {
        grid.start(x, y).min(self.triangle_count().saturating_sub(1))
    }

    /// The first step of [`Mesh::interpolate_with_grid`] alone: the plane of the triangle at
    /// the query's grid cell there, and whether that triangle holds the query with a finite
    /// value (then the value is [`Mesh::interpolate_with_grid`]'s, bit for bit). No branch on
    /// the outcome; see [`crate::Axis::evaluate_in_grid_cell`].
    #[inline]
    pub fn interpolate_in_grid_cell(&self, x: f32, y: f32, grid: &StartGrid<'_>) -> (MeshValue, bool) {
        let start = self.grid_cell_triangle(grid, x, y);
        match self.hint_test(x, y, start) {
            Some(test) => (test.value, test.inside & test.value.value_dph.is_finite()),
            None => (MeshValue { value_dph: f32::NAN, triangle: start, outside_hull: false }, false),
        }
    }

    /// The general path of [`Mesh::interpolate_with_grid`]: a non-finite query, a hint past
    /// the last triangle, a non-finite plane value. Out of line.
    #[cold]
    #[inline(never)]
    fn interpolate_grid_general(
        &self,
        x: f32,
        y: f32,
        hint: &mut WalkHint,
        grid: &StartGrid<'_>,
    ) -> Result<MeshValue, Error> {
        if !(x.is_finite() && y.is_finite()) {
            return Err(Error::NonFiniteSample);
        }
        let count = self.triangle_count();
        let start = if hint.0 < count { hint.0 } else { 0 };
        let end = match self.walk(NO_NEIGHBOUR, start, x, y, 0) {
            Some(end) if end.inside => Some(end),
            _ => self.walk_or_scan(x, y, self.grid_cell_triangle(grid, x, y)),
        }
        .ok_or(Error::BadMesh { check: "walk", axis: self.axis, index: start })?;
        hint.0 = end.triangle;
        Ok(self.value_at(&end, x, y))
    }

    /// Fills `cells` (at least `side * side` long) with, for each cell of a `side x side`
    /// grid over the mesh's bounding box, the triangle containing (or nearest to) the cell
    /// centre, and returns the grid. Done once at start-up; no allocation.
    ///
    /// # Errors
    /// [`Error::BadValue`] if `side` is 0 or `cells` is too short.
    pub fn start_grid<'g>(&self, side: u32, cells: &'g mut [u32]) -> Result<StartGrid<'g>, Error> {
        let (needed, lo, per_unit) = self.grid_frame(side, cells.len())?;
        let mut hint = WalkHint::default();
        for (k, cell) in cells.iter_mut().take(needed).enumerate() {
            let side = side as usize;
            let (i, j) = (k.checked_rem(side).unwrap_or(0) as f32, k.checked_div(side).unwrap_or(0) as f32);
            let (x, y) = (lo[0] + (i + 0.5) / per_unit[0], lo[1] + (j + 0.5) / per_unit[1]);
            *cell = match self.locate(x, y, &mut hint)? {
                Location::Inside { triangle, .. } | Location::Outside { triangle } => triangle,
            };
        }
        let cells: &'g [u32] = cells;
        Ok(StartGrid { lo, per_unit, side, cells: cells.get(..needed).unwrap_or(&[]) })
    }

    /// A start grid from `cells` that [`Mesh::start_grid`] filled earlier with the same `side`
    /// for this mesh (kept by a caller that evaluates many batches). Any cell content is safe:
    /// a start triangle out of range is clamped, a wrong one only lengthens the walk.
    ///
    /// # Errors
    /// [`Error::BadValue`] if `side` is 0 or `cells` is too short.
    pub fn grid_from_cells<'g>(&self, side: u32, cells: &'g [u32]) -> Result<StartGrid<'g>, Error> {
        let (needed, lo, per_unit) = self.grid_frame(side, cells.len())?;
        Ok(StartGrid { lo, per_unit, side, cells: cells.get(..needed).unwrap_or(&[]) })
    }

    /// Cells needed, lower corner and cells per unit of a `side x side` grid over the mesh's
    /// bounding box.
    fn grid_frame(&self, side: u32, cells_len: usize) -> Result<(usize, [f32; 2], [f32; 2]), Error> {
        let needed = (side as usize).checked_mul(side as usize).filter(|&n| n > 0);
        let Some(needed) = needed.filter(|&n| n <= cells_len) else {
            return Err(Error::BadValue { field: "start grid side", axis: self.axis, index: side });
        };
        let (mut lo, mut hi) = ([f32::INFINITY; 2], [f32::NEG_INFINITY; 2]);
        for v in (0..self.vertex_count()).filter_map(|i| self.vertex(i)) {
            lo = [lo[0].min(v.x), lo[1].min(v.y)];
            hi = [hi[0].max(v.x), hi[1].max(v.y)];
        }
        let span = [(hi[0] - lo[0]).max(f32::MIN_POSITIVE), (hi[1] - lo[1]).max(f32::MIN_POSITIVE)];
        Ok((needed, lo, [side as f32 / span[0], side as f32 / span[1]]))
    }

    /// The value at a walk's end: the plane inside, the outside policy beyond the hull.
    #[inline(always)]
    fn value_at(&self, end: &WalkEnd<'_>, x: f32, y: f32) -> MeshValue {
        if end.inside {
            let r = end.record;
            let (dx, dy) = end.delta;
            let p = TRI_PLANE.start;
            let value_dph = rec_f32(r, p) * dx + rec_f32(r, p + 4) * dy + rec_f32(r, p + 8);
            return MeshValue { value_dph, triangle: end.triangle, outside_hull: false };
        }
        self.outside_value(end.triangle, most_negative(end.bary).0, x, y)
    }

    /// The outside policy's value at a query a walk took out of the mesh across edge `k` of
    /// `triangle`.
    #[inline(always)]
    fn outside_value(&self, triangle: u32, k: usize, x: f32, y: f32) -> MeshValue {
        let value_dph = match self.policy {
            // Scalars, not the walk's end by reference: the hot inside path keeps the walk's end
            // in registers (with `&WalkEnd` passed on, the inside points of the 1 M-point Python
            // benchmark took 20 % longer, docs/performance.md).
            OutsidePolicy::NearestHull => self.hull_value_after_walk(triangle, k, x, y),
            OutsidePolicy::Zero => 0.0,
            OutsidePolicy::LinearFromBoundary => self.linear_value_after_walk(triangle, k, x, y),
            OutsidePolicy::StoredGradients => self.stored_value_after_walk(triangle, k, x, y),
        };
        MeshValue { value_dph, triangle, outside_hull: true }
    }

    /// The policy `LinearFromBoundary`'s value (see `src/beyond.rs`); where the nearest hull
    /// point cannot be found (a non-finite query), the hull value as `NearestHull` gives it.
    #[cold]
    #[inline(never)]
    fn linear_value_after_walk(&self, triangle: u32, k: usize, x: f32, y: f32) -> f32 {
        match crate::beyond::linear_value(self, x, y) {
            Some(value) => value,
            None => self.hull_value_after_walk(triangle, k, x, y),
        }
    }

    /// The policy `StoredGradients`'s value (see `src/beyond.rs`); where the nearest hull point
    /// cannot be found (a non-finite query), the hull value as `NearestHull` gives it.
    #[cold]
    #[inline(never)]
    fn stored_value_after_walk(&self, triangle: u32, k: usize, x: f32, y: f32) -> f32 {
        match crate::beyond::stored_gradient_value_after_walk(self, triangle, k, x, y) {
            Some(value) => value,
            None => self.hull_value_after_walk(triangle, k, x, y),
        }
    }

    /// [`Mesh::nearest_hull_value`] for a query a walk took out of the mesh: starts from the
    /// hull edge the walk crossed (the most negative barycentric coordinate of the last
    /// triangle) instead of searching the hull for an edge facing the query. The same
    /// certificates and the same value rule, so the same value (two certificates can both hold
    /// only within rounding of a Voronoi boundary); the search when the crossed edge and its
    /// ends do not hold the nearest point.
    #[cold]
    #[inline(never)]
    fn hull_value_after_walk(&self, triangle: u32, k: usize, x: f32, y: f32) -> f32 {
        let on_edge = crate::hull::value_on_crossed_edge(self, triangle, k, x, y);
        match on_edge.or_else(|| crate::hull::value_from_slot(self, triangle, k, x, y)) {
            Some(value) => value,
            None => self.nearest_hull_value(x, y),
        }
    }

    /// Value at the point of the hull nearest to `(x, y)`, linear along the hull edge, for a
    /// query outside the hull. O(log hull edges) in the typical case (see `src/hull.rs`):
    /// the hull edge facing the query by a binary search over the fan of hull vertices
    /// around an interior point, then a descent along the hull to the edge or vertex whose
    /// normal cone holds the query; the value there with the arithmetic of
    /// [`Mesh::nearest_hull_value_by_scan`] (at a vertex, its choice between the two edges),
    /// so it is that scan's bit for bit unless another edge ties within f32 rounding. When the
    /// geometry cannot be certified (a non-finite query, a degenerate hull, rounding right
    /// on the hull), the scan decides.
    #[cold]
    #[inline(never)]
    pub fn nearest_hull_value(&self, x: f32, y: f32) -> f32 {
        match crate::hull::nearest_edge(self, x, y).and_then(|n| self.certified_value(n, x, y)) {
            Some(value) => value,
            None => self.nearest_hull_value_by_scan(x, y),
        }
    }

    /// The hull edge around which [`Mesh::nearest_hull_value`] certified the nearest hull point
    /// of `(x, y)` (the point lies on this edge or at its start vertex), or `None` where it
    /// falls back to the scan. For tests and benchmarks.
    #[doc(hidden)]
    pub fn nearest_hull_edge(&self, x: f32, y: f32) -> Option<u32> {
        crate::hull::nearest_edge(self, x, y).map(crate::hull::Nearest::edge)
    }

    /// Value at the point of the hull nearest to `(x, y)` by scanning every hull edge: the
    /// reference [`Mesh::nearest_hull_value`] must agree with, and its fallback. O(hull edges).
    /// Ties go to the lower edge index; a NaN or infinite query gives 0.
    pub fn nearest_hull_value_by_scan(&self, x: f32, y: f32) -> f32 {
        let mut best = (f32::INFINITY, 0.0f32);
        for h in 0..self.hull_edge_count() {
            let Some((a, b)) = self.hull_edge_vertices(h) else { continue };
            let (d2, value) = edge_nearest(&a, &b, x, y);
            if d2 < best.0 {
                best = (d2, value);
            }
        }
        best.1
    }

    /// The value at a certified nearest point (see `src/hull.rs`, step 3).
    fn certified_value(&self, nearest: crate::hull::Nearest, x: f32, y: f32) -> Option<f32> {
        match nearest {
            crate::hull::Nearest::Edge(h) => {
                let (a, b) = self.hull_edge_vertices(h)?;
                Some(edge_nearest(&a, &b, x, y).1)
            }
            crate::hull::Nearest::Vertex(h) => {
                let before = self.hull_edge_vertices(crate::hull::cyclic(h, -1, self.hull_edge_count()))?;
                let after = self.hull_edge_vertices(h)?;
                Some(crate::hull::vertex_value((&before.0, &before.1), (&after.0, &after.1), h == 0, x, y))
            }
        }
    }

    /// Position of the start vertex of hull edge `index` (the end vertex of edge `index - 1`),
    /// read straight from the records.
    #[inline]
    pub(crate) fn hull_start(&self, index: u32) -> Option<[f32; 2]> {
        let at = (self.hull_start_index(index)? as usize).checked_mul(VERTEX_LEN)?;
        Some([wire::f32_at(self.vertices, at)?, wire::f32_at(self.vertices, at.checked_add(4)?)?])
    }

    /// Vertex indices and neighbours of triangle `t`, read straight from its record.
    #[inline(always)]
    pub(crate) fn corners(&self, t: u32) -> Option<([u32; 3], [u32; 3])> {
        let r = self.record(t)?;
        let (v, n) = (TRI_VERTICES.start, TRI_NEIGHBOURS.start);
        Some((
            [rec_u32(r, v), rec_u32(r, v + 4), rec_u32(r, v + 8)],
            [rec_u32(r, n), rec_u32(r, n + 4), rec_u32(r, n + 8)],
        ))
    }

    /// Index of the start vertex of hull edge `index`.
    #[inline]
    pub(crate) fn hull_start_index(&self, index: u32) -> Option<u32> {
        let (t, e) = self.hull_edge(index)?;
        // Edge e runs from vertex e + 1 to e + 2 of its triangle.
        let k = match e {
            0 => 1,
            1 => 2,
            2 => 0,
            _ => return None,
        };
        Some(rec_u32(self.record(t)?, TRI_VERTICES.start + 4 * k))
    }

    /// The start and end vertex of hull edge `index` (counter-clockwise order).
    pub fn hull_edge_vertices(&self, index: u32) -> Option<(Vertex, Vertex)> {
        let (t, e) = self.hull_edge(index)?;
        let rec = self.triangle(t)?;
        let (ia, ib) = edge_vertices(&rec, e)?;
        Some((self.vertex(ia)?, self.vertex(ib)?))
    }
}

/// What [`Mesh::hint_test`] found in the hint triangle.
#[derive(Clone, Copy)]
struct HintTest<'a> {
    /// The query is inside (or on the boundary of) the hint triangle.
    inside: bool,
    /// The hint triangle's plane at the query (meaningful when `inside`).
    value: MeshValue,
    /// The hint triangle's record.
    record: &'a [u8; TRIANGLE_LEN],
    /// The index of the most negative coordinate: the edge a walk leaves across.
    exit: usize,
}

/// Where a walk ended: the triangle, its record, the query's barycentric coordinates in it,
/// and whether the query is inside (else the walk crossed a hull edge of this triangle).
struct WalkEnd<'a> {
    triangle: u32,
    record: &'a [u8; TRIANGLE_LEN],
    /// The query relative to the record's origin.
    delta: (f32, f32),
    bary: [f32; 3],
    inside: bool,
}

/// A grid of walk start triangles over the mesh's bounding box, in a caller-owned buffer
/// (see [`Mesh::start_grid`]).
#[derive(Clone, Copy, Debug)]
pub struct StartGrid<'g> {
    lo: [f32; 2],
    per_unit: [f32; 2],
    side: u32,
    cells: &'g [u32],
}

impl StartGrid<'_> {
    /// The start triangle for `(x, y)` (the nearest cell for points off the grid).
    #[inline(always)]
    fn start(&self, x: f32, y: f32) -> u32 {
        let i = cell_index((x - self.lo[0]) * self.per_unit[0], self.side);
        let j = cell_index((y - self.lo[1]) * self.per_unit[1], self.side);
        self.cells.get(j * self.side as usize + i).copied().unwrap_or(0)
    }
}

/// The cell holding grid coordinate `v` (cells per unit from the grid's corner) on a side of
/// `side` cells, the nearest cell off the grid; 0 for NaN.
///
/// Truncated to an integer first and clamped there: `as i32` saturates (NaN gives 0), so this
/// is the cell of clamping `v` to `[0, side - 1]` before truncating, in about a third of the
/// instructions (a float-to-`usize` conversion with its saturation costs two conversions and
/// several fix-ups on x86-64, and the float clamp a branch; docs/performance.md).
#[inline(always)]
fn cell_index(v: f32, side: u32) -> usize {
    let last = i32::try_from(side).unwrap_or(i32::MAX).saturating_sub(1);
    (v as i32).min(last).max(0) as usize
}

/// f32 at a fixed offset of a triangle record (inlined to a plain load).
#[inline(always)]
fn rec_f32(r: &[u8; TRIANGLE_LEN], offset: usize) -> f32 {
    r.get(offset..offset + 4).and_then(|b| b.first_chunk::<4>()).map_or(f32::NAN, |b| f32::from_le_bytes(*b))
}

/// u32 at a fixed offset of a triangle record.
#[inline(always)]
fn rec_u32(r: &[u8; TRIANGLE_LEN], offset: usize) -> u32 {
    r.get(offset..offset + 4)
        .and_then(|b| b.first_chunk::<4>())
        .map_or(NO_NEIGHBOUR, |b| u32::from_le_bytes(*b))
}

/// Barycentric coordinates from a raw record.
#[inline(always)]
fn barycentric_rec(r: &[u8; TRIANGLE_LEN], x: f32, y: f32) -> [f32; 3] {
    let (dx, dy) = (x - rec_f32(r, TRI_ORIGIN.start), y - rec_f32(r, TRI_ORIGIN.start + 4));
    let b = TRI_BARY.start;
    let l0 = rec_f32(r, b) * dx + rec_f32(r, b + 4) * dy;
    let l1 = rec_f32(r, b + 8) * dx + rec_f32(r, b + 12) * dy;
    [l0, l1, 1.0 - l0 - l1]
}

/// Squared distance from `(x, y)` to segment `a b` and the value there (linear along the
/// segment). The one arithmetic of every hull-value path, so they agree bit for bit.
#[inline(always)]
pub(crate) fn edge_nearest(a: &Vertex, b: &Vertex, x: f32, y: f32) -> (f32, f32) {
    let (dx, dy) = (b.x - a.x, b.y - a.y);
    let len2 = dx * dx + dy * dy;
    let s = if len2 > 0.0 { (((x - a.x) * dx + (y - a.y) * dy) / len2).clamp(0.0, 1.0) } else { 0.0 };
    let (px, py) = (a.x + s * dx, a.y + s * dy);
    let d2 = (x - px) * (x - px) + (y - py) * (y - py);
    (d2, a.value_dph + s * (b.value_dph - a.value_dph))
}

/// Vertex indices `(from, to)` of edge `edge` (the edge opposite vertex `edge`).
pub(crate) fn edge_vertices(rec: &TriangleRecord, edge: u32) -> Option<(u32, u32)> {
    let e = edge as usize;
    let from = rec.vertices.get((e + 1) % 3)?;
    let to = rec.vertices.get((e + 2) % 3)?;
    (e < 3).then_some((*from, *to))
}

/// Barycentric coordinates of `(x, y)` in the triangle `rec`.
#[inline(always)]
pub(crate) fn barycentric(rec: &TriangleRecord, x: f32, y: f32) -> [f32; 3] {
    let (dx, dy) = (x - rec.origin[0], y - rec.origin[1]);
    let b = &rec.bary;
    let l0 = b[0] * dx + b[1] * dy;
    let l1 = b[2] * dx + b[3] * dy;
    [l0, l1, 1.0 - l0 - l1]
}

/// The triangle's value plane at `(x, y)`.
#[inline(always)]
pub(crate) fn plane_value(rec: &TriangleRecord, x: f32, y: f32) -> f32 {
    let (dx, dy) = (x - rec.origin[0], y - rec.origin[1]);
    rec.plane[0] * dx + rec.plane[1] * dy + rec.plane[2]
}

/// Index and value of the smallest coordinate. Validated records give finite
/// coordinates for finite queries; should a NaN appear anyway, the walk stays bounded.
#[inline(always)]
fn most_negative(l: [f32; 3]) -> (usize, f32) {
    let [l0, l1, l2] = l;
    let (mut k, mut m) = (0, l0);
    if l1 < m {
        (k, m) = (1, l1);
    }
    if l2 < m {
        (k, m) = (2, l2);
    }
    (k, m)
}
