//! Touches in sockets simulated with a known truth: what a robot with given geometric errors
//! would record, for checking a calibration from touches against the truth it should find.
//!
//! The configurations come from real ones (a recorded layout, `templates`), so their spread is a
//! real protocol's. Each socket is put where the true robot holds the ball on average over its
//! template configurations (with a known distance, the second socket is moved along the line
//! between the two to lie exactly that far from the first). Each configuration is then moved,
//! by the least joint motion ([`crate::kinematics::reach::reach_point`]), until
//! the true ball centre lies at its socket's centre plus the ball's play, drawn per touch from
//! `N(0, play^2)` on every axis. The joint readings are recorded exactly.
//!
//! Planes (given by their normals) pass through each placement's first socket; their contacts
//! start from the same template configurations, the true ball moved onto the plane and spread
//! over it by a grid of in-plane offsets (160 mm across), off it by the play along the normal.

use crate::io::sockets::{Placement, Reading, Socket};
use calib_core::model::JointVec;
use calib_core::{Kinematics, ParameterErrors, Robot};
use nalgebra::{Dyn, Vector3};
use rand_core::SeedableRng;
use rand_distr::{Distribution, Normal};
use rand_xoshiro::Xoshiro256PlusPlus;
use std::path::PathBuf;

/// How close the true ball must come to its target, mm.
const REACHED_MM: f64 = 1e-9;

/// What to simulate.
#[derive(Clone, Debug, PartialEq)]
pub struct TouchSimulation {
    /// The true errors of the robot (its tool frame is the ball's centre), mm and rad.
    pub truth: ParameterErrors<f64, Dyn>,
    /// The ball's play in its socket: the standard deviation of the ball centre's offset from
    /// the socket's centre on every axis, mm.
    pub play_sd_mm: f64,
    /// A known distance between two sockets of every placement (socket numbers, mm).
    pub gauge: Option<([u16; 2], f64)>,
    /// The normals of planes every placement holds beside its sockets (unit vectors in the base
    /// frame), each through the true centre of the placement's first socket.
    pub planes: Vec<[f64; 3]>,
    /// Seed of the play's draws.
    pub seed: u64,
}

/// The true socket centres of one simulated placement, mm (base frame).
#[derive(Clone, Debug, PartialEq)]
pub struct SimulatedPlacement {
    /// The touches, as a recorded layout holds them.
    pub placement: Placement,
    /// The sockets' true centres, in socket order, mm.
    pub centres_mm: Vec<[f64; 3]>,
}

/// The touches `robot` (the ball its tool) with `simulation.truth` would record near the
/// configurations of `templates`. Refused: a negative or non-finite play, a gauge naming a
/// socket a placement lacks, a configuration the true ball cannot be moved to its socket from.
pub fn simulate_touches(
    robot: &Robot<f64, Dyn>,
    simulation: &TouchSimulation,
    templates: &[Placement],
) -> crate::Result<Vec<SimulatedPlacement>> {
    if !(simulation.play_sd_mm.is_finite() && simulation.play_sd_mm >= 0.0) {
        return Err(crate::refused!(option "play";
            "a ball's play of {} mm: give a standard deviation of at least 0 mm", simulation.play_sd_mm));
    }
    let truth = Kinematics::new(robot, &simulation.truth)?;
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(simulation.seed);
    let play = Normal::new(0.0, simulation.play_sd_mm)
        .map_err(|e| crate::refused!(option "play"; "the ball's play: {e}"))?;
    (templates.iter())
        .map(|template| {
            let centres = socket_centres(&truth, template, simulation.gauge)?;
            let sockets = (template.sockets.iter().zip(&centres))
                .enumerate()
                .map(|(s, (socket, centre))| {
                    let readings = (socket.readings.iter())
                        .map(|r| {
                            let target = centre + Vector3::from_fn(|_, _| play.sample(&mut rng));
                            let q_rad = reach(&truth, &r.q_rad, &target).ok_or_else(|| {
                                crate::refused!(input socket.path.display();
                                    "{}:{}: the true ball cannot be moved to its socket from this configuration",
                                    socket.path.display(), r.line)
                            })?;
                            Ok(Reading { line: r.line, q_rad })
                        })
                        .collect::<crate::Result<Vec<Reading>>>()?;
                    Ok(Socket {
                        path: PathBuf::from(format!("simulated/{}/hole_{s}.csv", template.name)),
                        readings,
                    })
                })
                .collect::<crate::Result<Vec<Socket>>>()?;
            let planes = (simulation.planes.iter().enumerate())
                .map(|(k, normal)| {
                    let through = centres.first().copied().unwrap_or_else(Vector3::zeros);
                    plane_contacts(&truth, template, (k, normal), through, (&play, &mut rng))
                })
                .collect::<crate::Result<Vec<Socket>>>()?;
            Ok(SimulatedPlacement {
                placement: Placement {
                    name: template.name.clone(),
                    sockets,
                    planes,
                },
                centres_mm: centres.iter().map(|c| (*c).into()).collect(),
            })
        })
        .collect()
}

/// In-plane offsets of the contacts, mm: a 5 x 5 grid over 160 mm, gone through in turn.
const SPREAD_MM: [f64; 5] = [-80.0, -40.0, 0.0, 40.0, 80.0];

/// The contacts of plane `k` (unit normal `normal`, through `through`, mm) near the template's
/// configurations: each one's true ball projected onto the plane, moved in it by the next
/// offset of a grid, then off it by the ball's play along the normal.
fn plane_contacts(
    truth: &Kinematics<f64, Dyn>,
    template: &Placement,
    (k, normal): (usize, &[f64; 3]),
    through: Vector3<f64>,
    (play, rng): (&Normal<f64>, &mut Xoshiro256PlusPlus),
) -> crate::Result<Socket> {
    let path = PathBuf::from(format!("simulated/{}/plane_{k}.csv", template.name));
    let n = Vector3::from(*normal).try_normalize(1e-12).ok_or_else(
        || crate::refused!(option "planes"; "plane {k}: its normal {normal:?} has no direction"),
    )?;
    let helper = if n.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let (u, v) = (
        n.cross(&helper).normalize(),
        n.cross(&n.cross(&helper)).normalize(),
    );
    let mut readings = Vec::new();
    let every = template.sockets.iter().flat_map(|s| &s.readings);
    for (i, r) in every.enumerate() {
        let p = ball(truth, &r.q_rad).ok_or_else(|| {
            crate::refused!(input path.display(); "{}: not a joint vector of this robot", r.line)
        })?;
        let on_plane = p - n * n.dot(&(p - through));
        let grid = u * SPREAD_MM[i % 5] + v * SPREAD_MM[(i / 5) % 5];
        let target = on_plane + grid + n * play.sample(rng);
        let q_rad = reach(truth, &r.q_rad, &target).ok_or_else(|| {
            crate::refused!(input path.display();
                "{}: plane {k}: the true ball cannot be moved onto the plane from line {}", template.name, r.line)
        })?;
        readings.push(Reading {
            line: r.line,
            q_rad,
        });
    }
    Ok(Socket { path, readings })
}

/// The true ball centre at joint readings `q` (rad), mm.
fn ball(truth: &Kinematics<f64, Dyn>, q: &[f64]) -> Option<Vector3<f64>> {
    let q = JointVec::from_slice(q)?;
    Some(truth.forward(&q).ok()?.translation.vector)
}

/// Each socket's centre: the true ball's mean over its template configurations; with a gauge,
/// its second socket moved along the line from the first to lie the gauge's length from it.
fn socket_centres(
    truth: &Kinematics<f64, Dyn>,
    template: &Placement,
    gauge: Option<([u16; 2], f64)>,
) -> crate::Result<Vec<Vector3<f64>>> {
    let mut centres = Vec::with_capacity(template.sockets.len());
    for socket in &template.sockets {
        let mut sum = Vector3::zeros();
        for r in &socket.readings {
            sum += ball(truth, &r.q_rad).ok_or_else(|| {
                crate::refused!(input socket.path.display();
                    "{}:{}: not a joint vector of this robot", socket.path.display(), r.line)
            })?;
        }
        centres.push(sum / socket.readings.len().max(1) as f64);
    }
    if let Some(([a, b], mm)) = gauge {
        let (Some(first), Some(second)) = (
            centres.get(usize::from(a)).copied(),
            centres.get(usize::from(b)).copied(),
        ) else {
            return Err(crate::refused!(option "gauge";
                "placement {}: no sockets {a} and {b} for the known distance", template.name));
        };
        let direction = (second - first).try_normalize(1e-9).ok_or_else(|| {
            crate::refused!(input template.name.as_str();
                "placement {}: sockets {a} and {b} coincide; no direction to set the distance along", template.name)
        })?;
        centres[usize::from(b)] = first + direction * mm;
    }
    Ok(centres)
}

/// The joint readings nearest `start` at which the true ball lies at `target` (mm).
fn reach(truth: &Kinematics<f64, Dyn>, start: &[f64], target: &Vector3<f64>) -> Option<Vec<f64>> {
    crate::kinematics::reach::reach_point(truth, start, target, REACHED_MM)
}
