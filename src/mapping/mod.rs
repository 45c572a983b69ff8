//! Mapping: range data into occupancy grids, topological graphs and merged multi-drone maps.

pub mod scan;
