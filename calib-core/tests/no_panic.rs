//! Property tests: random models, targets, measurements and garbage bytes never make the core
//! panic; bad input comes back as an error (or, for pure math on garbage, a non-finite value).

use calib_core::controller::compensate::{CompensationSettings, compensate_joints, predistort};
use calib_core::controller::storage;
use calib_core::identify::halton::{Scrambling, halton_point};
use calib_core::identify::lm::{LeastSquares, LmSettings, Loss};
use calib_core::identify::objective::{Measurement, Objective};
use calib_core::math::so3;
use calib_core::model::paper::{er10l_c10, table2};
use calib_core::{Kinematics, MdhJoint, ParameterErrors, ParameterSet, Pose, Problem, Robot};
use nalgebra::U6;
use nalgebra::{Matrix3, Rotation3, SVector, Translation3, U24, Vector3};
use proptest::prelude::*;

/// Any f64, NaN and infinities included, with ordinary values most of the time.
fn value() -> impl Strategy<Value = f64> {
    prop_oneof![
        8 => -2000.0..2000.0f64,
        1 => any::<f64>(),
        1 => prop::sample::select(vec![f64::NAN, f64::INFINITY, f64::NEG_INFINITY, 0.0, -0.0, 1e308, -1e-308]),
    ]
}

fn robot() -> impl Strategy<Value = Robot<f64, U6>> {
    prop::array::uniform6((value(), value(), value(), value(), value())).prop_map(|joints| {
        Robot::from_joints(joints.map(|(a, alpha, theta_offset, d, beta)| MdhJoint {
            a,
            alpha,
            theta_offset,
            d,
            beta,
        }))
    })
}

fn pose() -> impl Strategy<Value = Pose<f64>> {
    (
        prop::array::uniform3(value()),
        prop::array::uniform3(value()),
    )
        .prop_map(|(t, r)| {
            Pose::from_parts(
                Translation3::new(t[0], t[1], t[2]),
                Rotation3::from_matrix_unchecked(Matrix3::new(
                    r[0], r[1], r[2], r[1], r[2], r[0], r[2], r[0], r[1],
                )),
            )
        })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 300, .. ProptestConfig::default() })]

    #[test]
    fn kinematics_never_panics(robot in robot(), q in prop::array::uniform6(value())) {
        match Kinematics::new(&robot, &ParameterErrors::zero()) {
            Ok(k) => {
                let _ = k.forward(&q);
                let _ = k.geometric_jacobian(&q);
            }
            Err(e) => prop_assert!(!e.to_string().is_empty()),
        }
    }

    #[test]
    fn compensation_never_panics(target in pose(), q in prop::array::uniform6(value())) {
        let nominal = Kinematics::nominal(&er10l_c10::<f64>()).unwrap();
        let actual = Kinematics::new(&er10l_c10::<f64>(), &table2::<f64>()).unwrap();
        let limits = er10l_c10::<f64>().limits;
        let settings = CompensationSettings::default();
        if let Ok(c) = compensate_joints(&nominal, &actual, &limits, &target, &q, &settings) {
            prop_assert!(c.residual_mm <= settings.position_tolerance);
        }
        let _ = predistort(&nominal, &actual, &limits, &target, &q, &settings);
    }

    #[test]
    fn f32_compensation_never_panics(target in pose(), q in prop::array::uniform6(value())) {
        let nominal = Kinematics::nominal(&er10l_c10::<f32>()).unwrap();
        let target32 = Pose::<f32>::from_parts(
            Translation3::from(target.translation.vector.map(|v| v as f32)),
            Rotation3::from_matrix_unchecked(target.rotation.matrix().map(|v| v as f32)),
        );
        let _ = compensate_joints(&nominal, &nominal, &er10l_c10::<f32>().limits, &target32, &q.map(|v| v as f32), &CompensationSettings::default());
    }

    #[test]
    fn storage_decode_never_panics(bytes in prop::collection::vec(any::<u8>(), 0..600)) {
        let _ = storage::decode::<f64, U6>(&bytes);
        let _ = storage::decode::<f32, U6>(&bytes);
        let _ = storage::decode_model::<f32, U6, 64>(&bytes);
    }

    #[test]
    fn storage_decode_of_a_version_2_header_with_any_body_never_panics(
        harmonics in any::<u16>(),
        body in prop::collection::vec(any::<u8>(), 0..4000),
    ) {
        let mut bytes = b"CALB\x02\x00\x04\x06\x01\x00\x00\x00".to_vec();
        bytes.extend_from_slice(&harmonics.to_le_bytes());
        bytes.extend_from_slice(&[0, 0]);
        bytes.extend_from_slice(&body);
        let _ = storage::decode_model::<f32, U6, 64>(&bytes);
        let _ = storage::decode_model::<f32, U6, 0>(&bytes);
    }

    #[test]
    fn measurements_and_solvers_never_panic(
        q in prop::array::uniform6(value()),
        p in prop::array::uniform3(value()),
        r in prop::array::uniform3(value()),
        w in value(),
        x in prop::array::uniform6(value()),
    ) {
        let rotation = Rotation3::new(Vector3::from(r)).into_inner();
        let robot = er10l_c10::<f64>();
        let set = ParameterSet::<U6, U24>::default_for(&robot).unwrap();
        let measured = Measurement::new(&q, Vector3::from(p), Some(rotation), w);
        if let Ok(m) = measured {
            let data = [m; 30];
            let mut start = SVector::<f64, 24>::zeros();
            for (s, v) in start.iter_mut().zip(x.iter().cycle()) {
                *s = *v;
            }
            if let Ok(problem) = Problem::new(&robot, &ParameterErrors::zero(), set, &data, 1e6) {
                let _ = Objective::new(&problem).value(&start);
                let least_squares = LeastSquares::new(&problem);
                let settings = LmSettings { max_iterations: 5, ..LmSettings::default() };
                let _ = least_squares.solve(&start, &settings);
                let mut weights = [0.0; 30];
                let _ = least_squares.solve_robust(&start, &settings, Loss::Huber(0.5), &mut weights);
            }
        }
    }

    #[test]
    fn rotation_math_and_halton_never_panic(m in prop::array::uniform9(value()), index in any::<u64>()) {
        let matrix = Matrix3::from_row_slice(&m);
        let _ = so3::log(&matrix);
        let _ = so3::right_jacobian_inverse(&Vector3::new(m[0], m[1], m[2]));
        let _ = so3::angle_squared_between(&matrix, &Matrix3::identity());
        let mut point = [0.0; 64];
        halton_point(index, Scrambling::Reverse, &mut point);
        prop_assert!(point.iter().all(|v| (0.0..1.0).contains(v)));
    }
}

/// A run-time (`Dyn`) parameter count holds a start vector of any length: one that is not the
/// set's length is refused by least squares with both lengths, and has no objective value
/// (+infinity), instead of a panic in nalgebra (too long) or a value of a truncated vector (too
/// short).
#[test]
fn dyn_vectors_of_another_length_are_refused() {
    use nalgebra::{DVector, Dyn};
    let robot = er10l_c10::<f64>().recount::<Dyn>().unwrap();
    let set = ParameterSet::<Dyn, Dyn>::default_for(&robot).unwrap();
    let truth = Kinematics::new(&er10l_c10::<f64>(), &table2::<f64>()).unwrap();
    let data: Vec<Measurement<f64, Dyn>> = (0..30)
        .map(|i| {
            let q = [0.1 * i as f64, -0.5, 0.3, 0.2 * i as f64, 0.7, -0.1];
            let pose = truth.forward(&q).unwrap();
            Measurement::<f64, U6>::new(
                &q,
                pose.translation.vector,
                Some(*pose.rotation.matrix()),
                1.0,
            )
            .unwrap()
            .recount()
            .unwrap()
        })
        .collect();
    let zero = ParameterErrors::zeros_for(robot.joint_count());
    let problem = Problem::new(&robot, &zero, set, &data, 1e6).unwrap();
    let parameters = problem.set().len();
    assert_eq!(parameters, 24);
    let objective = Objective::new(&problem);
    let least_squares = LeastSquares::new(&problem);
    let settings = LmSettings {
        max_iterations: 3,
        ..LmSettings::default()
    };
    for length in [0, 1, 23, 25, 48] {
        let x = DVector::<f64>::zeros(length);
        assert_eq!(objective.value(&x), f64::INFINITY, "length {length}");
        let refused = least_squares.solve(&x, &settings).err();
        assert_eq!(
            refused,
            Some(calib_core::identify::lm::LmError::Shape {
                expected: 24,
                got: length as u32
            }),
            "length {length}"
        );
        let mut weights = vec![1.0; data.len()];
        assert!(
            least_squares
                .solve_robust(&x, &settings, Loss::Huber(1.0), &mut weights)
                .is_err()
        );
        // Every other entry of a packed vector: refused with both lengths (issue 53, item 5).
        let shape = calib_core::model::parameters::ShapeError {
            expected: 24,
            got: length,
        };
        let lm_shape = calib_core::identify::lm::LmError::from(shape);
        let set = problem.set();
        assert_eq!(set.unpack(&x), Err(shape), "length {length}");
        let mut errors = ParameterErrors::zeros_for(robot.joint_count());
        errors.joints[1].da = 0.25;
        let kept = errors;
        assert_eq!(set.unpack_into(&x, &mut errors), Err(shape));
        assert_eq!(errors, kept, "a refused vector changes nothing");
        let own = DVector::<f64>::zeros(parameters);
        assert_eq!(set.largest_differences(&x, &own), Err(shape));
        assert_eq!(set.largest_differences(&own, &x), Err(shape));
        assert_eq!(problem.errors(&x).err(), Some(shape));
        assert_eq!(problem.kinematics(&x).err(), Some(shape));
        assert_eq!(objective.pose_errors(&x, |_, _| {}), Err(shape));
        assert_eq!(least_squares.cost(&x), Err(lm_shape));
        assert_eq!(least_squares.jacobian_factor(&x).err(), Some(lm_shape));
        let mut norms = vec![0.0; data.len()];
        assert_eq!(
            least_squares.pose_residual_norms(&x, &mut norms),
            Err(lm_shape)
        );
        assert_eq!(
            calib_core::identify::ipso::SearchSpace::around(x.clone(), own.clone(), 2.0).err(),
            Some(calib_core::identify::ipso::IpsoError::InvalidSize)
        );
    }
    // The set's own length: a finite value and a solution, and the same values from every entry.
    let x = DVector::<f64>::zeros(parameters);
    assert!(objective.value(&x).is_finite() && objective.value(&x) > 0.0);
    assert!(least_squares.solve(&x, &settings).is_ok());
    let cost = least_squares.cost(&x).unwrap();
    // The poses' residual norms make up least squares' cost 0.5 |r|^2 (unit weights).
    let mut norms = vec![0.0; data.len()];
    least_squares.pose_residual_norms(&x, &mut norms).unwrap();
    let sum: f64 = norms.iter().map(|n| n * n).sum();
    assert!((sum - 2.0 * cost).abs() <= 1e-9 * cost);
    assert_eq!(
        least_squares.pose_residual_norms(&x, &mut norms[1..]),
        Err(calib_core::identify::lm::LmError::WeightBuffer)
    );
    assert_eq!(problem.set().unpack(&x).unwrap(), zero);
}

/// Common points (issue 53, item 7): a start vector of another length is refused by every entry,
/// touches without weight or without partners leave rows out instead of dividing by zero, and
/// no touches at all are refused as too few residuals.
#[test]
fn common_points_refuse_what_they_cannot_fit() {
    use calib_core::identify::common_point::{CommonPoints, Touch};
    use calib_core::identify::lm::LmError;
    use nalgebra::{DVector, Dyn};
    let robot = er10l_c10::<f64>().recount::<Dyn>().unwrap();
    let set = ParameterSet::<Dyn, Dyn>::default_for(&robot).unwrap();
    let zero = ParameterErrors::zeros_for(robot.joint_count());
    let q = |i: usize| {
        calib_core::model::JointVec::from_slice(&[0.1 * i as f64, -0.5, 0.3, 0.2, 0.7, -0.1])
            .unwrap()
    };
    // Point 0: two touches of weight 0; point 1: one touch; point 3: ten touches (point 2: none).
    let mut touches = vec![
        Touch::new(&q(0), 0, 0.0).unwrap(),
        Touch::new(&q(1), 0, 0.0).unwrap(),
        Touch::new(&q(2), 1, 1.0).unwrap(),
    ];
    touches.extend((3..13).map(|i| Touch::new(&q(i), 3, 1.0).unwrap()));
    let problem = CommonPoints::new(&robot, &zero, set.clone(), &touches).unwrap();
    let least_squares = LeastSquares::new(&problem);
    // 3 (10 - 1) rows from point 3, 3 (2 - 1) from point 0 (counted, weighted zero), 0 from 1.
    assert_eq!(least_squares.rows(), 30);
    let settings = LmSettings {
        max_iterations: 3,
        ..LmSettings::default()
    };
    for length in [0, 23, 25] {
        let x = DVector::<f64>::zeros(length);
        let shape = LmError::Shape {
            expected: 24,
            got: length as u32,
        };
        assert_eq!(least_squares.solve(&x, &settings).err(), Some(shape));
        assert_eq!(least_squares.cost(&x).err(), Some(shape));
        assert_eq!(problem.centre_at(&x, 3).err().map(|e| e.got), Some(length));
    }
    let x = DVector::<f64>::zeros(24);
    assert!(least_squares.cost(&x).unwrap().is_finite());
    assert_eq!(problem.centre_at(&x, 0).unwrap(), None);
    assert_eq!(problem.centre_at(&x, 2).unwrap(), None);
    let mut norms = vec![f64::NAN; touches.len()];
    least_squares.pose_residual_norms(&x, &mut norms).unwrap();
    assert_eq!(norms[2], 0.0, "a point touched once is its own centre");
    assert!(
        norms[..2].iter().all(|n| n.is_nan()),
        "weight 0: no centre, no norm"
    );
    let none: [Touch<f64, Dyn>; 0] = [];
    let empty = CommonPoints::new(&robot, &zero, set, &none).unwrap();
    assert_eq!(
        LeastSquares::new(&empty).solve(&x, &settings).err(),
        Some(LmError::TooFewResiduals {
            rows: 0,
            parameters: 24
        })
    );
}
