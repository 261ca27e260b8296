//! A plan of touches (issue 54): which arm configurations to record in each socket of a
//! placement, and what a calibration from them will give. It lives with the calibration from
//! touches because it plans for that calibration: the same kind, the same selection of
//! parameters, the same covariance.
//!
//! Candidates: configurations of the nominal robot with the ball at a socket, reached from a
//! Halton sequence of starts over the joint limits ([`crate::kinematics::reach::reach_point`]),
//! so that a 7-joint arm's null space and a 6-joint arm's wrist orientations are spread; those
//! outside the joint limits are dropped. The choice: greedy D-optimal, one socket after the
//! other, each time the candidate that most increases `log det` of the information matrix of
//! the touches' kind (`sum over sockets of sum_i J_i^T J_i - n mean J^T mean J`, the sockets'
//! centres eliminated, plus the known distance's row), `J_i` the ball's position Jacobian over
//! the identified parameters. The prediction: the parameters' covariance `sigma^2 I^-1` for a
//! touch scatter `sigma` per coordinate, the consistency these configurations should show when
//! measured again after the calibration
//! ([`crate::analysis::consistency_prediction::predict_consistency`]), and how well the known
//! distance (the scale) is held. Beside it, the same prediction for the first reachable
//! candidates in Halton order, so the plan's gain is stated, not assumed.

use super::touches::{Gauge, TouchSession, touches_of};
use super::{CalibrationConfig, select_parameters_of};
use crate::analysis::consistency_prediction::{PredictedConsistency, predict_consistency};
use crate::analysis::identifiability::FreeParameter;
use crate::io::robot_file::RobotFile;
use crate::io::sockets::{Placement, Reading, Socket};
use calib_core::identify::common_point::Touch;
use calib_core::model::JointVec;
use calib_core::model::parameters::FrameParameter;
use calib_core::{Kinematics, Parameter, ParameterSet};
use nalgebra::{DMatrix, DVector, Dyn, Vector3};
use std::path::PathBuf;

/// What to plan.
#[derive(Clone, Debug)]
pub struct TouchPlanRequest {
    /// The nominal robot file and where it was read from.
    pub robot: RobotFile,
    /// Its path (named in errors).
    pub robot_path: PathBuf,
    /// The ball's centre in the robot file's tool frame, mm.
    pub ball_mm: [f64; 3],
    /// The sockets' centres of the placement, base frame, mm.
    pub sockets_mm: Vec<[f64; 3]>,
    /// Configurations to record per socket.
    pub per_socket: usize,
    /// Starting configurations tried per socket (the candidates are those that reach it).
    pub starts: usize,
    /// The touches' expected scatter per coordinate, mm (the Pandas: about 0.1).
    pub touch_sd_mm: f64,
    /// The known distance between two sockets, if any.
    pub gauge: Option<Gauge>,
    /// Candidate places for the next placement of the sockets: where its first socket would go
    /// (the others keep their offsets from it), base frame, mm. Each is planned the same way
    /// and ranked by what it adds to this plan.
    pub next: Vec<[f64; 3]>,
}

/// A candidate place for the next placement, with what it would add.
#[derive(Clone, Debug, PartialEq)]
pub struct NextPlacement {
    /// Where its first socket goes, base frame, mm.
    pub first_socket_mm: [f64; 3],
    /// Candidates reaching its least reachable socket within the joint limits.
    pub reachable: usize,
    /// The geometric mean of the parameters' predicted standard errors (mm and rad mixed, so
    /// only for comparing places) with its planned touches added to the plan's; `None` when a
    /// socket is out of reach.
    pub geometric_std_error: Option<f64>,
}

/// One configuration to record.
#[derive(Clone, Debug, PartialEq)]
pub struct PlannedTouch {
    /// The socket, numbered as given.
    pub socket: u16,
    /// The joints, rad.
    pub q_rad: Vec<f64>,
}

/// What a set of touches predicts.
#[derive(Clone, Debug, PartialEq)]
pub struct TouchPrediction {
    /// Each identified parameter's predicted standard error (mm or rad).
    pub std_errors: Vec<(Parameter, f64)>,
    /// The consistency of these configurations measured again after the calibration, mm.
    pub consistency: Option<PredictedConsistency>,
    /// The known distance's predicted standard error after the calibration, mm.
    pub distance_sd_mm: Option<f64>,
}

/// A plan of touches.
#[derive(Clone, Debug)]
pub struct TouchPlan {
    /// The configurations, socket by socket.
    pub touches: Vec<PlannedTouch>,
    /// Candidates that reached each socket within the joint limits.
    pub reachable: Vec<usize>,
    /// The parameters a calibration from these touches identifies.
    pub set: ParameterSet<Dyn, Dyn>,
    /// What touches leave free whatever the configurations.
    pub left_free: Vec<FreeParameter>,
    /// Parameters the candidates barely determine (dropped, as a calibration would).
    pub dropped: Vec<Parameter>,
    /// The plan's prediction.
    pub predicted: TouchPrediction,
    /// The same for the first reachable candidates in Halton order.
    pub first_reachable: TouchPrediction,
    /// The candidate places of the next placement, best first (out of reach last).
    pub next: Vec<NextPlacement>,
}

/// Plans the touches of `request`. Refused: no socket, fewer than four configurations per
/// socket, a scatter or distance that is not positive, a socket fewer than `per_socket`
/// candidates reach within the joint limits.
pub fn plan_touches(request: &TouchPlanRequest) -> crate::Result<TouchPlan> {
    check(request)?;
    let session = TouchSession {
        robot: request.robot.clone(),
        robot_path: request.robot_path.clone(),
        ball_mm: request.ball_mm,
        placements: Vec::new(),
        train: Vec::new(),
        gauge: request.gauge,
        datums: Vec::new(),
        config: CalibrationConfig::default(),
        compliance: false,
    };
    let ball = session.ball_model()?;
    let nominal = Kinematics::nominal(&ball.robot)?;
    let starts =
        crate::planning::generate(&request.robot, &request.robot_path, request.starts, None)?;
    let candidates: Vec<Vec<Vec<f64>>> = (request.sockets_mm.iter())
        .map(|socket| reachable(&nominal, &ball.robot, &starts, socket))
        .collect();
    let reachable: Vec<usize> = candidates.iter().map(Vec::len).collect();
    if let Some((s, n)) = (reachable.iter().enumerate()).find(|(_, n)| **n < request.per_socket) {
        return Err(crate::refused!(option "--socket";
            "socket {s} at {:?} mm: {n} of {} starts reach it within the joint limits, fewer than the {} asked per socket; move it within reach, or give more --starts",
            request.sockets_mm[s], request.starts, request.per_socket));
    }
    let weight = request
        .gauge
        .map(|g| (request.touch_sd_mm / g.sd_mm).powi(2));
    let selection = selection_of(&ball, &candidates, request.gauge.as_ref().zip(weight))?;
    let set = crate::model::counts::solvable_set(&selection.mask)?;
    let jacobians = jacobians_of(&nominal, &set, &candidates)?;
    let gauge = request.gauge.zip(weight);
    let none = DMatrix::zeros(set.len(), set.len());
    let chosen = greedy(
        &jacobians,
        (&request.sockets_mm, request.per_socket),
        gauge,
        &none,
    );
    let base = information(&sums_of(&jacobians, &chosen), gauge, &request.sockets_mm);
    let context = Context {
        nominal: &nominal,
        robot: &ball.robot,
        starts: &starts,
        set: &set,
        gauge,
    };
    let next = rank_next(&context, request, &base)?;
    let touches: Vec<PlannedTouch> = (chosen.iter().enumerate())
        .flat_map(|(s, picks)| picks.iter().map(move |i| (s, *i)))
        .map(|(s, i)| PlannedTouch {
            socket: s as u16,
            q_rad: candidates[s][i].clone(),
        })
        .collect();
    let first: Vec<Vec<usize>> = vec![(0..request.per_socket).collect(); candidates.len()];
    let candidates = Candidates {
        joints: candidates,
        jacobians,
    };
    let predict =
        |picks: &[Vec<usize>]| prediction(&nominal, &set, (&candidates, picks), request, gauge);
    Ok(TouchPlan {
        predicted: predict(&chosen)?,
        first_reachable: predict(&first)?,
        touches,
        reachable,
        set,
        left_free: selection.identifiability.left_free.clone(),
        dropped: selection.dropped.clone(),
        next,
    })
}

/// The parameters a calibration from every candidate would identify: the robot file's, the
/// ball's offset, less what touches leave free and what the candidates barely determine.
fn selection_of(
    ball: &super::touches::BallModel,
    candidates: &[Vec<Vec<f64>>],
    gauge: Option<(&Gauge, f64)>,
) -> crate::Result<super::Selection> {
    let everything = placement_of(candidates);
    let data = touches_of(&[&everything], gauge, &[])?;
    let mut mask = ball.mask;
    for axis in [FrameParameter::Tx, FrameParameter::Ty, FrameParameter::Tz] {
        mask.set(Parameter::Tool(axis), true);
    }
    let config = CalibrationConfig {
        auto_mask: true,
        ..CalibrationConfig::default()
    };
    select_parameters_of(&data.kind(&ball.robot), mask, &config)
}

/// The ball's position Jacobians of every candidate, per socket.
fn jacobians_of(
    nominal: &Kinematics<f64, Dyn>,
    set: &ParameterSet<Dyn, Dyn>,
    candidates: &[Vec<Vec<f64>>],
) -> crate::Result<Vec<Vec<DMatrix<f64>>>> {
    (candidates.iter())
        .map(|socket| {
            (socket.iter())
                .map(|q| position_jacobian(nominal, set, q))
                .collect()
        })
        .collect()
}

/// What planning another placement needs: the nominal model (the ball its tool), the starts,
/// the identified set, the gauge with its weight.
struct Context<'a> {
    nominal: &'a Kinematics<f64, Dyn>,
    robot: &'a calib_core::Robot<f64, Dyn>,
    starts: &'a [(String, Vec<f64>)],
    set: &'a ParameterSet<Dyn, Dyn>,
    gauge: Option<(Gauge, f64)>,
}

/// The candidate places of the next placement, each planned greedily on top of the plan's
/// information `base`, ranked by the geometric mean of the predicted standard errors.
fn rank_next(
    context: &Context<'_>,
    request: &TouchPlanRequest,
    base: &DMatrix<f64>,
) -> crate::Result<Vec<NextPlacement>> {
    let first = Vector3::from(request.sockets_mm[0]);
    let mut ranked = Vec::with_capacity(request.next.len());
    for at in &request.next {
        let shift = Vector3::from(*at) - first;
        let sockets: Vec<[f64; 3]> = (request.sockets_mm.iter())
            .map(|s| (Vector3::from(*s) + shift).into())
            .collect();
        let candidates: Vec<Vec<Vec<f64>>> = (sockets.iter())
            .map(|socket| reachable(context.nominal, context.robot, context.starts, socket))
            .collect();
        let reachable = candidates.iter().map(Vec::len).min().unwrap_or(0);
        let geometric_std_error = if reachable < request.per_socket {
            None
        } else {
            let jacobians = jacobians_of(context.nominal, context.set, &candidates)?;
            let picks = greedy(
                &jacobians,
                (&sockets, request.per_socket),
                context.gauge,
                base,
            );
            let info = base + information(&sums_of(&jacobians, &picks), context.gauge, &sockets);
            (info.try_inverse()).map(|inverse| {
                let sigma = request.touch_sd_mm;
                let logs: f64 = (0..inverse.nrows())
                    .map(|k| (inverse[(k, k)].max(1e-300) * sigma * sigma).sqrt().ln())
                    .sum();
                (logs / inverse.nrows().max(1) as f64).exp()
            })
        };
        ranked.push(NextPlacement {
            first_socket_mm: *at,
            reachable,
            geometric_std_error,
        });
    }
    ranked.sort_by(|a, b| {
        let key = |n: &NextPlacement| n.geometric_std_error.unwrap_or(f64::INFINITY);
        key(a).total_cmp(&key(b))
    });
    Ok(ranked)
}

/// Per socket, the sums of the candidates `picks` of `jacobians`.
fn sums_of(jacobians: &[Vec<DMatrix<f64>>], picks: &[Vec<usize>]) -> Vec<Sums> {
    let p = (jacobians.iter().flatten()).next().map_or(0, |j| j.ncols());
    (picks.iter().zip(jacobians))
        .map(|(picked, socket)| {
            let mut sum = (DMatrix::zeros(p, p), DMatrix::zeros(3, p), 0);
            for j in picked.iter().filter_map(|i| socket.get(*i)) {
                sum.0 += j.transpose() * j;
                sum.1 += j;
                sum.2 += 1;
            }
            sum
        })
        .collect()
}

impl TouchPlan {
    /// The plan as people read it: what was reachable, what touches leave free, the predicted
    /// standard errors and consistency beside the first reachable configurations'.
    pub fn text(&self) -> String {
        let per_socket = self.touches.iter().filter(|t| t.socket == 0).count();
        let mut text = format!(
            "planned {} configurations ({per_socket} per socket) from the candidates reaching each socket within the joint limits ({}), greedy D-optimal\n",
            self.touches.len(),
            (self.reachable.iter().map(ToString::to_string))
                .collect::<Vec<_>>()
                .join(", ")
        );
        text.push_str("left free by touches, whatever the configurations:\n");
        for f in &self.left_free {
            text.push_str(&format!("  {}: {}\n", f.parameter, f.why));
        }
        if !self.dropped.is_empty() {
            let dropped: Vec<String> = self.dropped.iter().map(ToString::to_string).collect();
            text.push_str(&format!(
                "barely determined from this placement (a calibration drops them): {}\n",
                dropped.join(", ")
            ));
        }
        text.push_str("\npredicted standard errors (mm, rad): planned / first reachable\n");
        for ((p, planned), (_, first)) in self
            .predicted
            .std_errors
            .iter()
            .zip(&self.first_reachable.std_errors)
        {
            text.push_str(&format!(
                "  {:<10} {planned:.3e} / {first:.3e}\n",
                p.to_string()
            ));
        }
        let line = |name: &str, p: &TouchPrediction| {
            let consistency = p.consistency.map_or("-".into(), |c| {
                format!(
                    "consistency {:.4} mm mean, {:.4} mm p95",
                    c.mean_mm, c.p95_mm
                )
            });
            let distance = p.distance_sd_mm.map_or(String::new(), |d| {
                format!(", the known distance held to {d:.4} mm")
            });
            format!("{name}: {consistency} when touched again after the calibration{distance}\n")
        };
        text.push('\n');
        text.push_str(&line("planned", &self.predicted));
        text.push_str(&line("first reachable", &self.first_reachable));
        text.push_str(&self.next_text());
        text.push_str(
            "the configurations are checked against the joint limits only: check each for collisions (the table, the sockets' tool) before moving there\n",
        );
        text
    }

    /// The candidate places of the next placement, best first, against the plan alone.
    fn next_text(&self) -> String {
        if self.next.is_empty() {
            return String::new();
        }
        let logs: Vec<f64> = self
            .predicted
            .std_errors
            .iter()
            .map(|(_, s)| s.ln())
            .collect();
        let alone = (logs.iter().sum::<f64>() / logs.len().max(1) as f64).exp();
        let mut text = format!(
            "\nthe next placement (its first socket at, mm; the others keep their offsets): geometric mean of the standard errors with it, against {alone:.3e} for this plan alone\n"
        );
        for n in &self.next {
            let [x, y, z] = n.first_socket_mm;
            let figure = n.geometric_std_error.map_or(
                format!(
                    "out of reach ({} candidates reach its least reachable socket)",
                    n.reachable
                ),
                |g| format!("{g:.3e} ({:.2} of the plan alone)", g / alone),
            );
            text.push_str(&format!("  {x:.1}, {y:.1}, {z:.1}: {figure}\n"));
        }
        text
    }

    /// The plan as our touch CSV (placement `planned`, the joints in degrees): the file the
    /// recorded readings then replace, line for line.
    pub fn csv(&self) -> String {
        let joints = self.touches.first().map_or(0, |t| t.q_rad.len());
        let mut csv = String::from("placement,socket");
        for j in 1..=joints {
            csv.push_str(&format!(",q{j}_deg"));
        }
        csv.push('\n');
        for t in &self.touches {
            let q: Vec<String> = t
                .q_rad
                .iter()
                .map(|v| format!("{:.6}", v.to_degrees()))
                .collect();
            csv.push_str(&format!("planned,{},{}\n", t.socket, q.join(",")));
        }
        csv
    }
}

/// Refuses a request that cannot be planned.
fn check(request: &TouchPlanRequest) -> crate::Result<()> {
    if request.sockets_mm.is_empty() || request.sockets_mm.len() >= usize::from(u16::MAX) {
        return Err(crate::refused!(option "--socket";
            "give the sockets' centres (--socket X,Y,Z in the base frame, mm; once per socket)"));
    }
    if request.per_socket < 4 || request.starts < request.per_socket {
        return Err(crate::refused!(option "--per-socket";
            "--per-socket {} with --starts {}: at least 4 configurations per socket, and at least as many starts",
            request.per_socket, request.starts));
    }
    let finite = |v: &[f64; 3]| v.iter().all(|x| x.is_finite());
    if !(request.sockets_mm.iter().all(finite) && finite(&request.ball_mm)) {
        return Err(
            crate::refused!(option "--socket"; "--socket and --ball-mm: finite numbers, mm"),
        );
    }
    if !(request.touch_sd_mm.is_finite() && request.touch_sd_mm > 0.0) {
        return Err(crate::refused!(option "--touch-sd";
            "--touch-sd {}: the touches' scatter per coordinate must be above 0 mm", request.touch_sd_mm));
    }
    if let Some(g) = &request.gauge {
        let count = request.sockets_mm.len();
        let known =
            g.sockets.iter().all(|s| usize::from(*s) < count) && g.sockets[0] != g.sockets[1];
        if !(known && g.mm.is_finite() && g.mm > 0.0 && g.sd_mm.is_finite() && g.sd_mm > 0.0) {
            return Err(crate::refused!(option "--distance";
                "--distance {} mm +- {} between sockets {:?}: two different sockets of the {count} given, a positive length and uncertainty",
                g.mm, g.sd_mm, g.sockets));
        }
    }
    Ok(())
}

/// The starts' configurations that put the nominal ball at `socket` (to 1e-6 mm) within the
/// joint limits, in the starts' order.
fn reachable(
    nominal: &Kinematics<f64, Dyn>,
    robot: &calib_core::Robot<f64, Dyn>,
    starts: &[(String, Vec<f64>)],
    socket: &[f64; 3],
) -> Vec<Vec<f64>> {
    let target = Vector3::from(*socket);
    (starts.iter())
        .filter_map(|(_, q)| crate::kinematics::reach::reach_point(nominal, q, &target, 1e-6))
        .filter(|q| (q.iter().zip(&robot.limits)).all(|(v, l)| (l.lower..=l.upper).contains(v)))
        .collect()
}

/// Candidates as one placement (socket `s`'s readings its candidates).
fn placement_of(candidates: &[Vec<Vec<f64>>]) -> Placement {
    Placement {
        name: "planned".into(),
        sockets: (candidates.iter().enumerate())
            .map(|(s, socket)| Socket {
                path: PathBuf::from(format!("planned/hole_{s}.csv")),
                readings: (socket.iter().enumerate())
                    .map(|(i, q)| Reading {
                        line: i as u64 + 1,
                        q_rad: q.clone(),
                    })
                    .collect(),
            })
            .collect(),
        planes: Vec::new(),
    }
}

/// The ball's position Jacobian (3 x parameters of `set`) at `q`.
fn position_jacobian(
    nominal: &Kinematics<f64, Dyn>,
    set: &ParameterSet<Dyn, Dyn>,
    q: &[f64],
) -> crate::Result<DMatrix<f64>> {
    let q = JointVec::from_slice(q).ok_or_else(|| {
        crate::refused!(implausible "joint count".to_string();
            "a planned configuration of {} joints: not a joint vector", q.len())
    })?;
    let touch = Touch::new(&q, 0, 1.0)
        .map_err(|e| crate::refused!(implausible format!("{e}"); "a planned configuration: {e}"))?;
    let (_, twist) = nominal.parameter_jacobian(set, &touch.angles);
    Ok(DMatrix::from_fn(3, set.len(), |r, c| twist[(r, c)]))
}

/// Per socket: the sum of `J^T J`, the sum of `J`, the count.
type Sums = (DMatrix<f64>, DMatrix<f64>, usize);

/// The information matrix of the sockets' sums, with the known distance's row.
fn information(sums: &[Sums], gauge: Option<(Gauge, f64)>, sockets: &[[f64; 3]]) -> DMatrix<f64> {
    let p = sums.first().map_or(0, |s| s.0.ncols());
    let mut info = DMatrix::zeros(p, p);
    for (s, m, n) in sums.iter().filter(|s| s.2 > 0) {
        info += s - m.transpose() * m / *n as f64;
    }
    if let Some((row, w)) = gauge.and_then(|(g, w)| Some((gauge_row(sums, &g, sockets)?, w))) {
        info += &row * row.transpose() * w;
    }
    info
}

/// The known distance's Jacobian row (over the parameters) between its sockets' centres,
/// `u^T (mean J_a - mean J_b)` with `u` the unit vector from socket `b` to `a`; `None` while a
/// socket has no touch.
fn gauge_row(sums: &[Sums], gauge: &Gauge, sockets: &[[f64; 3]]) -> Option<DVector<f64>> {
    let [a, b] = gauge.sockets.map(usize::from);
    let (sa, sb) = (
        sums.get(a).filter(|s| s.2 > 0)?,
        sums.get(b).filter(|s| s.2 > 0)?,
    );
    let u = (Vector3::from(*sockets.get(a)?) - Vector3::from(*sockets.get(b)?)).normalize();
    Some((&sa.1 / sa.2 as f64 - &sb.1 / sb.2 as f64).transpose() * u)
}

/// `log det` of `info` with a tiny ridge (so that the first picks, which cannot determine
/// everything yet, still compare), or minus infinity.
fn log_det(info: &DMatrix<f64>) -> f64 {
    let p = info.nrows().max(1);
    let ridge = 1e-9 * info.trace().abs().max(1e-12) / p as f64;
    let regular = info + DMatrix::identity(p, p) * ridge;
    regular.cholesky().map_or(f64::NEG_INFINITY, |c| {
        c.l().diagonal().iter().map(|d| 2.0 * d.ln()).sum()
    })
}

/// Greedy D-optimal choice: one candidate per socket in turn, the one raising `log det` most
/// (with the information `base` of touches already planned elsewhere), until every socket has
/// `per_socket`. Candidates' indices per socket, in the order chosen.
fn greedy(
    jacobians: &[Vec<DMatrix<f64>>],
    (sockets_mm, per_socket): (&[[f64; 3]], usize),
    gauge: Option<(Gauge, f64)>,
    base: &DMatrix<f64>,
) -> Vec<Vec<usize>> {
    let p = (jacobians.iter().flatten()).next().map_or(0, |j| j.ncols());
    let mut sums: Vec<Sums> =
        vec![(DMatrix::zeros(p, p), DMatrix::zeros(3, p), 0); jacobians.len()];
    let mut chosen: Vec<Vec<usize>> = vec![Vec::new(); jacobians.len()];
    for _ in 0..per_socket {
        for (s, socket) in jacobians.iter().enumerate() {
            let mut best: Option<(f64, usize)> = None;
            for (i, j) in socket.iter().enumerate() {
                if chosen[s].contains(&i) {
                    continue;
                }
                let mut trial = sums.clone();
                trial[s].0 += j.transpose() * j;
                trial[s].1 += j;
                trial[s].2 += 1;
                let value = log_det(&(information(&trial, gauge, sockets_mm) + base));
                if best.is_none_or(|(b, _)| value > b) {
                    best = Some((value, i));
                }
            }
            if let Some((_, i)) = best {
                let j = &socket[i];
                sums[s].0 += j.transpose() * j;
                sums[s].1 += j;
                sums[s].2 += 1;
                chosen[s].push(i);
            }
        }
    }
    chosen
}

/// The candidates of every socket: their joints (rad) and the ball's position Jacobians.
struct Candidates {
    joints: Vec<Vec<Vec<f64>>>,
    jacobians: Vec<Vec<DMatrix<f64>>>,
}

/// The prediction of the candidates `picks` (per socket) of `candidates`.
fn prediction(
    nominal: &Kinematics<f64, Dyn>,
    set: &ParameterSet<Dyn, Dyn>,
    (candidates, picks): (&Candidates, &[Vec<usize>]),
    request: &TouchPlanRequest,
    gauge: Option<(Gauge, f64)>,
) -> crate::Result<TouchPrediction> {
    let sums = sums_of(&candidates.jacobians, picks);
    let sigma = request.touch_sd_mm;
    let covariance = information(&sums, gauge, &request.sockets_mm)
        .try_inverse()
        .map(|inverse| inverse * sigma * sigma);
    let Some(covariance) = covariance else {
        return Err(
            crate::refused!(implausible "singular information".to_string();
            "the planned configurations cannot determine the parameters: give more --starts or another placement"),
        );
    };
    let std_errors = (set.parameters().iter().enumerate())
        .map(|(k, parameter)| (*parameter, covariance[(k, k)].max(0.0).sqrt()))
        .collect();
    let touches: Vec<Touch<f64, Dyn>> = (picks.iter().enumerate())
        .flat_map(|(s, picked)| picked.iter().map(move |i| (s, *i)))
        .filter_map(|(s, i)| {
            let q = JointVec::from_slice(&candidates.joints[s][i])?;
            Touch::new(&q, s as u16, 1.0).ok()
        })
        .collect();
    let distance_sd_mm = gauge.and_then(|(g, _)| {
        let row = gauge_row(&sums, &g, &request.sockets_mm)?;
        Some(
            (row.transpose() * &covariance * &row)[(0, 0)]
                .max(0.0)
                .sqrt(),
        )
    });
    Ok(TouchPrediction {
        std_errors,
        consistency: predict_consistency(nominal, set, &covariance, sigma, &touches),
        distance_sd_mm,
    })
}
