//! Integration tests of ferrofmm-tree, in one binary: each file below is a
//! module, so the generic driver is compiled once for all of them instead of
//! once per file.

mod common;
mod degenerate;
mod from_parts;
mod list_bounds;
mod morton_props;
mod periodic;
mod tree_props;
