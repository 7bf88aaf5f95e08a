//! Empty: it exists so that Cargo resolves the `[build-dependencies]` in
//! `Cargo.toml`, which are there only to give build-time code the same
//! dependency features in every build of `scripts/test` (see the comment
//! above them).
fn main() {}
