//! The end-to-end tests of the `sphereclip` command, one test binary (the layout of ripgrep's
//! `tests/`): each module a command or a promise, `util` their shared helpers and fixtures.

mod browser;
mod build;
mod cluster;
mod detail;
mod executables;
mod fidelity;
mod golden;
mod ingest;
mod ingest_edges;
mod input_fuzz;
mod inspect;
mod interop;
mod plan_safety;
mod render;
mod s3;
mod safety;
mod serve;
mod shading;
mod skyline;
mod store;
mod store_damage;
mod tidy;
mod usage;
mod util;
mod vector;
mod view_data;
