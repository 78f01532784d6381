//! fogtemp workspace root.
