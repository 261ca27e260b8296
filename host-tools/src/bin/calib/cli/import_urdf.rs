//! `calib import-urdf`: a robot's URDF as our robot file, exactly
//! ([`host_tools::formats::urdf_import`]).

use host_tools::io::outputs::Outputs;
use host_tools::io::robot_file::RobotFile;
use std::path::PathBuf;

/// Options of `calib import-urdf`.
#[derive(Clone, Debug, clap::Args)]
pub struct ImportUrdfOptions {
    /// The URDF file (metres and radians, as URDF has them).
    #[arg(value_name = "FILE")]
    pub urdf: PathBuf,
    /// The link the robot file's base frame is in (such as panda_link0).
    #[arg(long, value_name = "LINK")]
    pub base: String,
    /// The link the robot file's tool frame is (such as panda_link8, or a ball's link).
    #[arg(long, value_name = "LINK")]
    pub tip: String,
    /// The robot file to write.
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
}

/// Runs `calib import-urdf`: converts, reads the result back as a robot file (checked whole),
/// writes it; returns what to print.
pub fn import_urdf(options: &ImportUrdfOptions) -> anyhow::Result<String> {
    let toml = host_tools::formats::urdf_import::import_urdf_file(
        &options.urdf,
        &options.base,
        &options.tip,
    )?;
    let file = RobotFile::parse(&toml, &options.out)?;
    host_tools::kinematics::actual::ActualRobot::from_file(file.clone(), &options.out)?;
    let mut outputs = Outputs::new(&[("urdf", &options.urdf)]);
    outputs.stage("--out", &options.out, toml.as_bytes())?;
    outputs.commit()?;
    Ok(format!(
        "{}: {} revolute joints from {} to {}, the URDF's kinematics exactly; wrote {}\n",
        file.name,
        file.joint.len(),
        options.base,
        options.tip,
        options.out.display()
    ))
}
