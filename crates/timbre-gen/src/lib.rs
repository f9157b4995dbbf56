//! Random timbre trees: [`generate`] writes well-typed source text that always
//! compiles, is one lane wide and renders without blowing up; [`mutate`] makes
//! near-valid variations of a tree (for fuzzing the diagnostics). Used by property
//! tests, fuzz targets and `timbre-evolve`'s genetic search; nothing that renders a
//! scene depends on it.

pub mod generate;
pub mod mutate;
