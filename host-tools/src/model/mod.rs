//! The actual robot as the host models it, beyond the core's geometry: joint maps (each joint's
//! reading corrected by a smooth function of itself), compliance (deflection under gravity and
//! payload), and the joint and parameter counts every command checks a robot against. The whole
//! model as one value is `crate::kinematics::actual::ActualRobot` (it holds the robot file's
//! converted geometry, which `io` defines).

pub mod compliance;
pub mod counts;
pub mod joint_maps;

use calib_core::controller::storage::ControllerModel;
use compliance::FileCompliance;
use joint_maps::{JointMaps, MAX_FILE_HARMONICS};
use nalgebra::Dyn;

/// The controller's model in scalar `T`: `robot`, the maps (zero without) and the compliance
/// (none without).
pub(crate) fn controller_model<T: calib_core::Real>(
    robot: calib_core::Robot<T, Dyn>,
    maps: Option<&JointMaps>,
    compliance: Option<&FileCompliance>,
) -> crate::Result<ControllerModel<T, Dyn, MAX_FILE_HARMONICS>> {
    let joints = robot.joints.len();
    let mut model = ControllerModel::geometric(robot);
    if let Some(maps) = maps {
        model.maps = maps.to_core::<T, MAX_FILE_HARMONICS>()?;
    }
    if let Some(compliance) = compliance {
        model.compliance = compliance.to_core::<T>(joints)?;
    }
    Ok(model)
}
