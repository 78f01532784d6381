//! Discrepancy diagnosis: simulated vs recorded runs (work in progress).
