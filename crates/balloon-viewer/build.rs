//! Rebuilds the crate when the embedded page (`web/`) changes: `include_dir!` alone is not
//! tracked by Cargo on stable Rust.

fn main() {
    println!("cargo:rerun-if-changed=web");
    println!("cargo:rerun-if-changed=build.rs");
}
