//! The cross-crate tests, one test binary: each module is one concern (its file's doc says which).
//!
//! One binary instead of one per file: the workspace's release build links it once, and the two
//! firmware tests in QEMU (Rust and C, each about 20 s of one core) run side by side on the test
//! harness's threads instead of one after the other. `no_allocation` stays a binary of its own:
//! it counts the heap through its own global allocator.
//!
//! One module's tests: `cargo test --release -p calib-tests --test cross_crate -- onboard::`.

mod firmware_c_qemu;
mod firmware_qemu;
mod fk_reference;
mod golden_vectors;
mod onboard;
mod parameter_count;
mod robot_file;
mod swarm_golden;
mod tracker_data;
