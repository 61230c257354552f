//! Deeply nested vehicle files: importing, compiling, validating and
//! evaluating them must not depend on the thread's stack size. Each check
//! runs on a thread with a 256 KiB stack (a host may call an FMU's loader
//! from such a thread), thousands of levels deep.

use nudyn::mjcf::parse_mjcf;
use nudyn::model::Model;
use nudyn::vehicle::JointKind;

const DEPTH: usize = 5000;

/// Runs `check` on a thread with a small stack; a stack overflow aborts
/// the test binary, which fails the test run.
fn on_small_stack(check: impl FnOnce() + Send + 'static) {
    std::thread::Builder::new().stack_size(256 * 1024).spawn(check).unwrap().join().unwrap();
}

/// A free base carrying a chain of `DEPTH - 1` hinged bodies, each nested
/// in the one before.
fn deep_chain() -> String {
    let mut xml =
        String::from("<mujoco model=\"deep\"><worldbody><body name=\"b0\"><freejoint/><geom size=\"0.1\"/>\n");
    for i in 1..DEPTH {
        xml += &format!("<body name=\"b{i}\" pos=\"0 0 0.1\"><joint axis=\"1 0 0\"/><geom size=\"0.05\"/>\n");
    }
    xml += &"</body>".repeat(DEPTH);
    xml + "</worldbody></mujoco>"
}

#[test]
fn a_chain_thousands_deep_imports_compiles_and_evaluates() {
    on_small_stack(|| {
        let vehicle = parse_mjcf(&deep_chain()).unwrap().vehicle;
        assert_eq!(vehicle.bodies.len(), DEPTH);
        for (i, body) in vehicle.bodies.iter().enumerate() {
            assert_eq!(body.name, format!("b{i}"));
            assert_eq!(body.parent, i.checked_sub(1));
            assert_eq!(body.line as usize, i + 1, "{}", body.name);
        }
        let model = Model::compile(&vehicle).unwrap();
        model.validate().unwrap();
        assert_eq!((model.nq, model.nv), (7 + DEPTH - 1, 6 + DEPTH - 1));
        let back: Model = serde_json::from_str(&serde_json::to_string(&model).unwrap()).unwrap();
        assert_eq!(back, model);

        let mut ws = model.workspace();
        let nu: Vec<f64> = (0..model.nv).map(|i| 1e-3 * (i % 7) as f64).collect();
        nudyn::dynamics::forward(&model, &mut ws, &model.qpos0, &nu, &vec![0.0; model.nv]).unwrap();
        assert!(ws.nu_dot.iter().all(|a| a.is_finite()));
    });
}

#[test]
fn default_classes_thousands_deep_inherit_from_the_top() {
    on_small_stack(|| {
        let mut xml = String::from("<mujoco><default><joint damping=\"7\"/>");
        for i in 0..DEPTH {
            xml += &format!("<default class=\"c{i}\">");
        }
        xml += "<joint type=\"slide\"/>";
        xml += &"</default>".repeat(DEPTH + 1);
        let last = DEPTH - 1;
        xml +=
            &format!("<worldbody><body><joint name=\"j\" class=\"c{last}\"/><geom size=\"0.1\"/></body></worldbody>");
        xml += "</mujoco>";
        let vehicle = parse_mjcf(&xml).unwrap().vehicle;
        let joint = &vehicle.bodies[0].joints[0];
        assert_eq!((joint.kind, joint.damping), (JointKind::Slide, 7.0));
    });
}
