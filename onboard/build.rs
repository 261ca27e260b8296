//! Embeds the measurement set at build time: `data/paper32-noise.csv` (written by
//! `calib simulate`) becomes `OUT_DIR/scenario.rs`, the f32 bit patterns of every pose's joints
//! (rad), position (mm) and rotation matrix (row-major). The conversion runs here, on the build
//! machine, so the host test and the firmware embed identical bits.

// A build script reports bad input by failing the build with a message.
#![allow(
    clippy::panic,
    clippy::indexing_slicing,
    clippy::unwrap_used,
    clippy::expect_used
)]

use std::fmt::Write as _;

fn main() {
    let source = "data/paper32-noise.csv";
    println!("cargo:rerun-if-changed={source}");
    let text = std::fs::read_to_string(source).unwrap_or_else(|e| panic!("{source}: {e}"));
    let mut lines = text
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty());
    let header: Vec<&str> = lines.next().unwrap_or_default().split(',').collect();
    let expected = "id,q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg,x_mm,y_mm,z_mm,qw,qx,qy,qz";
    assert_eq!(header.join(","), expected, "{source}: unexpected header");
    let mut poses = String::new();
    let mut count = 0;
    for line in lines {
        let v: Vec<f64> = line
            .split(',')
            .skip(1)
            .map(|f| {
                f.parse()
                    .unwrap_or_else(|_| panic!("{source}: bad number in {line}"))
            })
            .collect();
        assert_eq!(v.len(), 13, "{source}: {line}");
        let (w, x, y, z) = (v[9], v[10], v[11], v[12]);
        let rotation = [
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y - w * z),
            2.0 * (x * z + w * y),
            2.0 * (x * y + w * z),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z - w * x),
            2.0 * (x * z - w * y),
            2.0 * (y * z + w * x),
            1.0 - 2.0 * (x * x + y * y),
        ];
        let values = v[..6]
            .iter()
            .map(|d| d.to_radians())
            .chain(v[6..9].iter().copied())
            .chain(rotation);
        poses.push_str("    [");
        for value in values {
            let _ = write!(poses, "0x{:08x}, ", (value as f32).to_bits());
        }
        poses.push_str("],\n");
        count += 1;
    }
    let out = format!(
        "/// Number of embedded poses.\npub const POSES: usize = {count};\n\
         /// Per pose: q1..q6 (rad), x, y, z (mm), rotation row-major, as f32 bits. On the\n\
         /// controller in the job's data region (`.calib_data`): measurements arrive at run time.\n\
         #[cfg_attr(target_os = \"none\", unsafe(link_section = \".calib_data\"))]\n\
         pub static SCENARIO: [[u32; 18]; POSES] = [\n{poses}];\n"
    );
    let dir = std::env::var("OUT_DIR").unwrap_or_else(|_| ".".into());
    std::fs::write(format!("{dir}/scenario.rs"), out).unwrap_or_else(|e| panic!("{e}"));
}
