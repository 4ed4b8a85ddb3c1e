//! Empty: it exists so the `[build-dependencies]` in Cargo.toml count (see there).
fn main() {
    println!("cargo:rerun-if-changed=build.rs");
}
