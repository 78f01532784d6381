//! Symmetric positive definite systems stored by their envelope (skyline), for the mesh's node
//! fit (`mesh_fit`): a mesh node couples only with nodes of neighbouring triangles, so after a
//! reverse Cuthill-McKee ordering ([`reverse_cuthill_mckee`]) the nonzeros of each row lie in a
//! short stretch left of the diagonal, and a Cholesky factorisation within that stretch costs
//! `O(n b^2)` for a profile of width `b`, against `O(n^3)` dense. The fill of a Cholesky factor
//! stays inside the envelope (George and Liu, *Computer Solution of Large Sparse Positive
//! Definite Systems*, 1981, ch. 4), so the factor is computed in place.

/// A symmetric matrix by the lower triangle of each row, from column `first[i]` to the diagonal.
#[derive(Clone, Debug, PartialEq)]
pub struct Envelope {
    /// First stored column of each row (at most the row's index).
    first: Vec<usize>,
    /// Offset of each row's first stored entry in `values`; one more entry at the end.
    start: Vec<usize>,
    values: Vec<f64>,
}

impl Envelope {
    /// A zero matrix whose row `i` stores columns `first[i]..=i` (a `first[i]` above `i` is
    /// read as `i`).
    pub fn zeros(first: &[usize]) -> Self {
        let first: Vec<usize> = first.iter().enumerate().map(|(i, &f)| f.min(i)).collect();
        let mut start = Vec::with_capacity(first.len() + 1);
        let mut at = 0;
        for (i, &f) in first.iter().enumerate() {
            start.push(at);
            at += i - f + 1;
        }
        start.push(at);
        Self { first, start, values: vec![0.0; at] }
    }

    /// Dimension.
    pub fn len(&self) -> usize {
        self.first.len()
    }

    /// Whether the matrix has no rows.
    pub fn is_empty(&self) -> bool {
        self.first.is_empty()
    }

    /// The stored entry `(i, j)` of the lower triangle (`j <= i`), or `None` outside the envelope.
    fn slot(&self, i: usize, j: usize) -> Option<usize> {
        (j <= i && j >= self.first[i]).then(|| self.start[i] + j - self.first[i])
    }

    /// Adds `value` to entry `(i, j)` and, by symmetry, `(j, i)`; `false` (nothing added) when
    /// the entry lies outside the envelope.
    pub fn add(&mut self, i: usize, j: usize, value: f64) -> bool {
        let (row, column) = if i >= j { (i, j) } else { (j, i) };
        match self.slot(row, column) {
            Some(k) => {
                self.values[k] += value;
                true
            }
            None => false,
        }
    }

    /// Entry `(i, j)`; zero outside the envelope.
    pub fn get(&self, i: usize, j: usize) -> f64 {
        let (row, column) = if i >= j { (i, j) } else { (j, i) };
        self.slot(row, column).map_or(0.0, |k| self.values[k])
    }

    /// Adds `scale` times `other` (the same envelope) to this matrix; `false` (nothing added)
    /// when the envelopes differ.
    pub fn add_scaled(&mut self, other: &Envelope, scale: f64) -> bool {
        if other.first != self.first {
            return false;
        }
        self.values.iter_mut().zip(&other.values).for_each(|(a, b)| *a += scale * b);
        true
    }

    /// This matrix with `rows` more rows and columns after it, each new row stored in full
    /// (from column 0: a border that couples with every earlier unknown), zero.
    pub fn with_full_rows(&self, rows: usize) -> Self {
        let mut first = self.first.clone();
        first.extend(std::iter::repeat_n(0, rows));
        let mut bordered = Self::zeros(&first);
        bordered.values[..self.values.len()].copy_from_slice(&self.values);
        bordered
    }

    /// The Cholesky factor `L` (`A = L L'`) in the same envelope, or `None` when a pivot is not
    /// positive and finite (the matrix is not positive definite in floating point).
    pub fn cholesky(mut self) -> Option<Self> {
        for i in 0..self.len() {
            let fi = self.first[i];
            for j in fi..=i {
                let fj = self.first[j];
                let from = fi.max(fj);
                // sum_k L[i][k] L[j][k] over the columns both rows store, left of j.
                let dot: f64 = (from..j)
                    .map(|k| self.values[self.start[i] + k - fi] * self.values[self.start[j] + k - fj])
                    .sum();
                let at = self.start[i] + j - fi;
                let a = self.values[at] - dot;
                if j == i {
                    if !(a > 0.0 && a.is_finite()) {
                        return None;
                    }
                    self.values[at] = a.sqrt();
                } else {
                    self.values[at] = a / self.values[self.start[j] + j - fj];
                }
            }
        }
        Some(self)
    }

    /// Solves `L L' x = b` in place, `self` being the factor [`Envelope::cholesky`] returned.
    pub fn solve_factored(&self, b: &mut [f64]) {
        let n = self.len().min(b.len());
        // Forward: L y = b, by rows.
        for i in 0..n {
            let fi = self.first[i];
            let row = &self.values[self.start[i]..self.start[i + 1]];
            let dot: f64 = (fi..i).map(|k| row[k - fi] * b[k]).sum();
            b[i] = (b[i] - dot) / row[i - fi];
        }
        // Backward: L' x = y, by columns of L' (rows of L), from the last.
        for i in (0..n).rev() {
            let fi = self.first[i];
            let row = &self.values[self.start[i]..self.start[i + 1]];
            b[i] /= row[i - fi];
            let xi = b[i];
            for k in fi..i {
                b[k] -= row[k - fi] * xi;
            }
        }
    }
}

/// A reverse Cuthill-McKee ordering of the graph `neighbours` (symmetric adjacency lists):
/// `order[p]` is the vertex placed at position `p`. Each connected part starts from a vertex
/// of least degree and is laid out breadth first, neighbours by increasing degree; the whole
/// order is then reversed, which keeps the envelope of a mesh's matrix narrow (George and Liu
/// 1981, ch. 4).
pub fn reverse_cuthill_mckee(neighbours: &[Vec<usize>]) -> Vec<usize> {
    let n = neighbours.len();
    let degree = |v: usize| neighbours[v].len();
    let mut placed = vec![false; n];
    let mut order = Vec::with_capacity(n);
    let mut by_degree: Vec<usize> = (0..n).collect();
    by_degree.sort_by_key(|&v| (degree(v), v));
    for &root in &by_degree {
        if placed[root] {
            continue;
        }
        placed[root] = true;
        let mut head = order.len();
        order.push(root);
        while head < order.len() {
            let v = order[head];
            head += 1;
            let mut next: Vec<usize> =
                neighbours[v].iter().copied().filter(|&w| w < n && !placed[w]).collect();
            next.sort_by_key(|&w| (degree(w), w));
            next.dedup();
            for w in next {
                placed[w] = true;
                order.push(w);
            }
        }
    }
    order.reverse();
    order
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{DMatrix, DVector};
    use rand::{Rng, SeedableRng};
    use rand_xoshiro::Xoshiro256PlusPlus;

    /// A random sparse symmetric positive definite matrix (a banded random pattern plus a
    /// dominant diagonal) and its envelope.
    fn random_spd(n: usize, band: usize, seed: u64) -> (DMatrix<f64>, Envelope) {
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
        let mut dense = DMatrix::<f64>::zeros(n, n);
        let mut first: Vec<usize> = (0..n).collect();
        for i in 0..n {
            for j in i.saturating_sub(band)..i {
                if rng.gen::<f64>() < 0.4 {
                    let v: f64 = rng.gen::<f64>() - 0.5;
                    dense[(i, j)] = v;
                    dense[(j, i)] = v;
                    first[i] = first[i].min(j);
                }
            }
        }
        for i in 0..n {
            let off: f64 = dense.row(i).iter().map(|v| v.abs()).sum();
            dense[(i, i)] = off + 0.1 + rng.gen::<f64>();
        }
        let mut envelope = Envelope::zeros(&first);
        for i in 0..n {
            for j in first[i]..=i {
                assert!(envelope.add(i, j, dense[(i, j)]));
            }
        }
        (dense, envelope)
    }

    /// Oracle: nalgebra's dense Cholesky solve; agreement to 1e-12 relative (both backward
    /// stable on a well-conditioned, diagonally dominant matrix).
    #[test]
    fn the_envelope_solve_matches_a_dense_cholesky() {
        for (n, band, seed) in [(1, 0, 1), (12, 3, 2), (80, 7, 3), (200, 25, 4)] {
            let (dense, envelope) = random_spd(n, band, seed);
            let b = DVector::from_fn(n, |i, _| (i as f64 * 0.37).sin());
            let reference = dense.clone().cholesky().expect("spd").solve(&b);
            let factor = envelope.cholesky().expect("spd");
            let mut x: Vec<f64> = b.iter().copied().collect();
            factor.solve_factored(&mut x);
            let scale = reference.amax();
            for (a, r) in x.iter().zip(reference.iter()) {
                assert!((a - r).abs() <= 1e-12 * scale, "n {n}: {a} vs {r}");
            }
        }
    }

    #[test]
    fn entries_outside_the_envelope_are_refused_and_read_as_zero() {
        let mut e = Envelope::zeros(&[0, 0, 2]);
        assert!(e.add(1, 0, 2.0) && e.add(0, 1, 1.0));
        assert_eq!(e.get(0, 1), 3.0);
        assert!(!e.add(2, 0, 5.0));
        assert_eq!(e.get(2, 0), 0.0);
        // Not positive definite: a zero pivot.
        assert!(e.clone().cholesky().is_none());
        let other = Envelope::zeros(&[0, 0, 0]);
        assert!(!e.add_scaled(&other, 1.0));
        // A border keeps every entry and stores its rows in full.
        let bordered = e.with_full_rows(2);
        assert_eq!(bordered.len(), 5);
        assert_eq!((bordered.get(0, 1), bordered.get(1, 1), bordered.get(2, 2)), (3.0, 0.0, 0.0));
        let mut bordered = bordered;
        assert!(bordered.add(4, 0, 1.5) && bordered.add(4, 3, 2.5));
        assert_eq!((bordered.get(0, 4), bordered.get(3, 4)), (1.5, 2.5));
    }

    /// A path graph given in scrambled order comes back as a path: every edge joins
    /// positions one apart (bandwidth 1), which the identity order of the scrambled labels
    /// does not give.
    #[test]
    fn reverse_cuthill_mckee_lays_a_scrambled_path_out_with_bandwidth_one() {
        let labels = [4usize, 0, 6, 2, 5, 1, 3]; // path: labels[0] - labels[1] - ...
        let mut neighbours = vec![Vec::new(); labels.len()];
        for w in labels.windows(2) {
            neighbours[w[0]].push(w[1]);
            neighbours[w[1]].push(w[0]);
        }
        let order = reverse_cuthill_mckee(&neighbours);
        let mut position = vec![0; order.len()];
        for (p, &v) in order.iter().enumerate() {
            position[v] = p;
        }
        let mut sorted = order.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, (0..labels.len()).collect::<Vec<_>>());
        for w in labels.windows(2) {
            assert_eq!(position[w[0]].abs_diff(position[w[1]]), 1, "{order:?}");
        }
        // Two parts and an isolated vertex: every vertex placed once.
        let parts = vec![vec![1], vec![0], vec![], vec![4], vec![3]];
        let mut order = reverse_cuthill_mckee(&parts);
        order.sort_unstable();
        assert_eq!(order, [0, 1, 2, 3, 4]);
    }
}
