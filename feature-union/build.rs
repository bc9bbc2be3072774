//! Does nothing: the build script exists so that this crate's
//! build-dependencies are built, with the features that the workspace's
//! proc-macros and build scripts ask of them (see Cargo.toml).

fn main() {}
