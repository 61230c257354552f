//! Cost of one ν̇ evaluation (all four passes) on each bundled example and
//! on a 200-body hinge chain on a free base, and of each pass alone; and of
//! one integrator stage (actuators, tendons, constraints) on the tendon
//! fixtures, with and without tendon armature.

use std::hint::black_box;
use std::path::Path;

use criterion::{Criterion, criterion_group, criterion_main};
use nudyn::dynamics::forward;
use nudyn::math::{Mat3, Quat, Vec3};
use nudyn::model::Model;
use nudyn::vehicle::{Actuation, Body, Joint, JointKind, MassProperties, Vehicle};

/// A chain of `links` hinge links on a free base, alternating hinge axes.
fn hinge_chain(links: usize) -> Vehicle {
    let mass = |m: f64| {
        Some(MassProperties { mass: m, com: Vec3::new(0.0, 0.0, 0.1), inertia: Mat3::from_diagonal_element(0.01 * m) })
    };
    let joint = |name: String, kind: JointKind, axis: Vec3| Joint {
        name,
        kind,
        pos: Vec3::zeros(),
        axis,
        reference: 0.0,
        springref: 0.0,
        stiffness: 0.0,
        damping: 0.0,
        armature: 0.0,
        actuator_force_range: None,
        actuator_gravcomp: false,
        springdamper: None,
        constraints: Default::default(),
        line: 0,
    };
    let mut bodies = vec![Body {
        name: "base".into(),
        parent: None,
        pos: Vec3::zeros(),
        quat: Quat::identity(),
        inertia: mass(100.0),
        inertial_pos: Vec3::zeros(),
        inertial_quat: Some(Quat::identity()),
        mass_unknown: false,
        joints: vec![joint("base".into(), JointKind::Free, Vec3::z())],
        gravcomp: 0.0,
        line: 0,
    }];
    for k in 1..=links {
        let axis = if k % 2 == 0 { Vec3::x() } else { Vec3::y() };
        bodies.push(Body {
            name: format!("link{k}"),
            parent: Some(k - 1),
            pos: Vec3::new(0.0, 0.0, 0.2),
            quat: Quat::identity(),
            inertia: mass(1.0),
            inertial_pos: Vec3::zeros(),
            inertial_quat: Some(Quat::identity()),
            mass_unknown: false,
            joints: vec![joint(format!("hinge{k}"), JointKind::Hinge, axis)],
            gravcomp: 0.0,
            line: 0,
        });
    }
    let (sites, actuators, sensors, actuation) = (Vec::new(), Vec::new(), Vec::new(), Actuation::default());
    let constraint_options = Default::default();
    Vehicle {
        name: format!("chain{links}"),
        gravity: Vec3::zeros(),
        magnetic: Vec3::zeros(),
        bodies,
        sites,
        actuators,
        sensors,
        actuation,
        constraint_options,
        equalities: Vec::new(),
        sensors_disabled: false,
        tendons: Vec::new(),
        flexible: Vec::new(),
    }
}

/// A deterministic, non-trivial state: every coordinate and velocity nonzero.
fn state(model: &Model) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let theta: Vec<f64> = model.qpos0.iter().enumerate().map(|(k, q)| q + 0.1 * ((k as f64) * 0.7).sin()).collect();
    let nu: Vec<f64> = (0..model.nv).map(|k| 0.3 * ((k as f64) * 1.3).cos()).collect();
    let eps: Vec<f64> = (0..model.nv).map(|k| 0.1 * ((k as f64) * 0.4).sin()).collect();
    (theta, nu, eps)
}

fn bench_model(c: &mut Criterion, name: &str, model: &Model) {
    let mut ws = model.workspace();
    let (theta, nu, eps) = state(model);
    c.bench_function(&format!("nu_dot/{name} (nv={})", model.nv), |b| {
        b.iter(|| forward(model, &mut ws, black_box(&theta), black_box(&nu), black_box(&eps)).unwrap())
    });
    // Where the time goes: each pass is timed after the ones it needs, so
    // a pass costs the difference between consecutive lines.
    c.bench_function(&format!("passes/{name}/0-1 configuration"), |b| {
        b.iter(|| ws.set_configuration(model, black_box(&theta)).unwrap())
    });
    c.bench_function(&format!("passes/{name}/2 velocity"), |b| {
        ws.set_configuration(model, &theta).unwrap();
        b.iter(|| ws.set_nu(model, black_box(&nu)).unwrap())
    });
    c.bench_function(&format!("passes/{name}/3 bias"), |b| {
        ws.set_configuration(model, &theta).unwrap();
        ws.set_nu(model, &nu).unwrap();
        b.iter(|| ws.compute_nu_dot(model, black_box(&eps)).unwrap())
    });
    // θ̈ instead of ν̇ (the integrators' state (θ, θ̇)): pass 3 without the
    // factor's rates, then the outward pass.
    c.bench_function(&format!("passes/{name}/3 bias without rates + accelerations"), |b| {
        ws.set_configuration(model, &theta).unwrap();
        ws.set_nu(model, &nu).unwrap();
        b.iter(|| ws.compute_qacc(model, black_box(&eps)).unwrap())
    });
}

/// One stage of the integrators as `rkmk` evaluates it: configuration,
/// velocities, then θ̈ with the actuators, the tendons' armature and the
/// constraint forces.
fn bench_stage(c: &mut Criterion, name: &str, model: &Model) {
    let mut ws = model.workspace();
    let (theta, qvel, eps) = state(model);
    let ctrl: Vec<f64> = (0..model.actuators.len()).map(|k| 0.5 * ((k as f64) * 0.9).cos()).collect();
    c.bench_function(&format!("stage/{name} (nv={})", model.nv), |b| {
        b.iter(|| {
            ws.set_configuration(model, black_box(&theta)).unwrap();
            ws.set_qvel(model, black_box(&qvel)).unwrap();
            ws.compute_qacc_actuated(model, black_box(&eps), black_box(&ctrl)).unwrap()
        })
    });
}

fn benches(c: &mut Criterion) {
    let fixtures = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/fixtures/tendons");
    for name in ["tendon_finger", "tendon_limits", "tendon_armature"] {
        // A fixture an older importer refuses is not timed (before/after runs).
        match nudyn::mjcf::load_mjcf(&fixtures.join(format!("{name}.xml"))) {
            Ok(imported) => bench_stage(c, name, &Model::compile(&imported.vehicle).expect("fixture compiles")),
            Err(error) => eprintln!("{name}: not timed ({error})"),
        }
    }
    let examples = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples");
    let mut files: Vec<_> = std::fs::read_dir(&examples)
        .expect("examples/ exists")
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "xml"))
        .collect();
    files.sort();
    for file in files {
        let imported = nudyn::mjcf::load_mjcf(&file).expect("example imports");
        let model = Model::compile(&imported.vehicle).expect("example compiles");
        bench_model(c, file.file_stem().unwrap().to_str().unwrap(), &model);
    }
    let chain = Model::compile(&hinge_chain(200)).unwrap();
    bench_model(c, "chain200", &chain);
}

criterion_group!(nu_dot_benches, benches);
criterion_main!(nu_dot_benches);
