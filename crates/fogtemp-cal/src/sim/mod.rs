//! Physics simulator of the lab experiment (work in progress).
