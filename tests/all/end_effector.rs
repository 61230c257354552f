//! `nudyn linearize`'s end-effector rows (`LinearOutput::EndEffector`)
//! against central differences of the body's pose from the configuration
//! passes (`control::body_pose`), with θ moved by the tests' own
//! `common::integrate_pos` (MuJoCo's mj_integratePos), on a
//! vehicle MuJoCo cannot model: a panel hanging on a hinge from a node of
//! a flexible body, whose pose moves with the body's modes
//! (tests/python/test_linearize.py checks the rigid examples against
//! MuJoCo's mj_jacBody).

use std::path::Path;

use nudyn::control::{BodyFrame, body_pose};
use nudyn::linearize::{Inputs, LinearOutput, OperatingPoint, linearize};
use nudyn::math::quat_difference;
use nudyn::mjcf::load_mjcf;
use nudyn::model::Model;

use crate::common::{Rng, integrate_pos};

#[test]
fn the_end_effector_rows_are_differences_of_its_pose_on_a_flexible_body() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/flex/bench_child.xml");
    let vehicle = load_mjcf(&path).unwrap().vehicle;
    let model = Model::compile(&vehicle).unwrap();
    let nv = model.nv;
    let mut rng = Rng::new(48);
    for body in ["panel", "bench"] {
        let frame = BodyFrame::find(&vehicle, &model, body).unwrap();
        let output = LinearOutput::EndEffector { link: frame.link, offset: frame.offset };
        for case in 0..3 {
            let qpos = integrate_pos(&vehicle, &model.qpos0, &rng.vec(nv, 0.3), 1.0);
            let point = OperatingPoint {
                qpos: qpos.clone(),
                qvel: rng.vec(nv, 0.5),
                act: Vec::new(),
                eps: vec![0.0; nv],
                torque: vec![0.0; nv],
                ctrl: Vec::new(),
            };
            let linear = linearize(&model, &point, Inputs::Eps, &[output], None).unwrap();
            assert_eq!(linear.c.shape(), (6, 2 * nv));
            assert!(linear.c.columns(nv, nv).iter().all(|&x| x == 0.0) && linear.d.iter().all(|&x| x == 0.0));
            let mut ws = model.workspace();
            let mut pose = |delta: &[f64]| {
                ws.set_configuration(&model, &integrate_pos(&vehicle, &qpos, delta, 1.0)).unwrap();
                body_pose(&model, &mut ws, &frame)
            };
            let (_, at) = pose(&vec![0.0; nv]);
            let h = 1e-6;
            let mut largest: f64 = 0.0;
            for k in 0..nv {
                let mut step = vec![0.0; nv];
                step[k] = h;
                let (p_plus, q_plus) = pose(&step);
                step[k] = -h;
                let (p_minus, q_minus) = pose(&step);
                let position = (p_plus - p_minus) / (2.0 * h);
                let turn = (quat_difference(&q_plus, &at) - quat_difference(&q_minus, &at)) / (2.0 * h);
                for r in 0..3 {
                    largest = largest.max((linear.c[(r, k)] - position[r]).abs());
                    largest = largest.max((linear.c[(3 + r, k)] - turn[r]).abs());
                }
            }
            let modal = model.flexible[0].dof_adr;
            let moves_with_modes = linear.c.view((0, modal), (6, 3)).iter().any(|x| x.abs() > 1e-3);
            assert_eq!(moves_with_modes, body == "panel", "{body} case {case}: the modes move the panel only");
            assert!(largest < 1e-8, "{body} case {case}: {largest:e} from the differences");
        }
    }
}
