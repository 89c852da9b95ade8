//! Runs each example of this folder as a test, so that `cargo test --workspace` (and CI) runs
//! them and they cannot rot.

#[allow(dead_code)]
#[path = "hanging_rope.rs"]
mod hanging_rope;

#[test]
fn hanging_rope_runs() {
    hanging_rope::main().expect("the hanging rope example");
}
