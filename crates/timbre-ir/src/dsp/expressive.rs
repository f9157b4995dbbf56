//! The 2006 schematic paper's expressive nodes.
