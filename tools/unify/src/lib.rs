//! No code: see Cargo.toml (feature unification between the workspace and python/).
