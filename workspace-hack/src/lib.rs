//! No code: see Cargo.toml. The crates built alone depend on it so that
//! their dependencies get the same features as in the workspace's build.
