//! Tendons from MJCF: what the importer and the compiler make of them, and
//! the refusals, each naming the element, its line and why (MuJoCo 4.0
//! refuses the same files, unless the message says nudyn does not model it).
//! The dynamics are checked against MuJoCo in tests/python/test_tendons.py.

use std::path::PathBuf;

use nudyn::mjcf::{MjcfError, load_mjcf, parse_mjcf};
use nudyn::model::{Model, Path};

fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/tendons").join(name)
}

/// A hinge, a slide and a ball joint on a free body, two sites and a geom;
/// `tendons` goes into `<tendon>` (line 11 onwards), `rest` after it.
fn scene(tendons: &str, rest: &str) -> String {
    format!(
        r#"<mujoco>
<worldbody>
<body name="base"><freejoint/><geom size="0.2"/>
<site name="s0" pos="0.1 0 0"/>
<body name="arm" pos="0.5 0 0">
<joint name="hinge" axis="0 1 0"/><joint name="slide" type="slide" axis="1 0 0"/>
<geom name="g" size="0.1"/><geom name="box" type="box" size="0.1 0.1 0.1"/><site name="s1" pos="0.3 0 0"/>
<body pos="0.3 0 0"><joint name="ball" type="ball"/><geom size="0.1"/></body></body></body>
</worldbody>
<tendon>
{tendons}
</tendon>
{rest}
</mujoco>"#
    )
}

fn refused(tendons: &str, rest: &str) -> MjcfError {
    match parse_mjcf(&scene(tendons, rest)) {
        Err(error) => error,
        Ok(_) => panic!("accepted: {tendons} {rest}"),
    }
}

#[test]
fn the_finger_compiles_with_mujocos_spring_lengths_and_qpos0_data() {
    let imported = load_mjcf(&fixture("tendon_finger.xml")).unwrap();
    let model = Model::compile(&imported.vehicle).unwrap();
    assert_eq!(model.tendons.len(), 3);
    assert!(matches!(model.tendons[0].path, Path::Fixed { ref terms } if terms.len() == 3));
    assert!(matches!(model.tendons[1].path, Path::Spatial { ref stops } if stops.len() == 8));
    // Default classes: "cable" gives the spatial tendon its stiffness and
    // damping, main its stiffness to the others.
    let stiffness: Vec<f64> = model.tendons.iter().map(|t| t.stiffness).collect();
    assert_eq!(stiffness, [3.0, 40.0, 3.0]);
    assert_eq!(model.tendons[1].damping, 0.5);
    // MuJoCo 4.0's tendon_lengthspring, tendon_length0, tendon_invweight0
    // and the servo's inherited ctrlrange for this file (its Python bindings).
    let spring: Vec<[f64; 2]> = model.tendons.iter().map(|t| t.spring_length).collect();
    assert_eq!(spring, [[-0.1, 0.2], [0.55, 0.55], [0.0, 0.0]]);
    let length0 = [0.0, 0.7754528418821949, 0.0];
    let invweight0 = [135.1922704231635, 9.1227239431221, 38.68817018198323];
    for (k, tendon) in model.tendons.iter().enumerate() {
        assert!((tendon.length0 - length0[k]).abs() < 1e-14, "{k}: {}", tendon.length0);
        assert!((tendon.invweight0 / invweight0[k] - 1.0).abs() < 1e-12, "{k}: {}", tendon.invweight0);
    }
    let [low, high] = model.actuators[0].ctrl_range.unwrap();
    assert!((low + 1.2).abs() < 1e-15 && (high - 1.2).abs() < 1e-15);
    // MuJoCo's biasprm[2] from dampratio 0.7: −0.7·2√(kp·m), m = 1/(J M⁻¹ Jᵀ) in qpos0.
    assert!((model.actuators[0].bias[2] / -0.17028135707728473 - 1.0).abs() < 1e-12, "{}", model.actuators[0].bias[2]);
    assert_eq!(model.constraints.tendon_friction.len(), 1);
    assert_eq!(model.constraints.tendon_limits.len(), 1);
}

#[test]
fn a_compiled_model_with_a_tendon_outside_it_is_refused() {
    let model = Model::compile(&load_mjcf(&fixture("tendon_finger.xml")).unwrap().vehicle).unwrap();
    let mut off_the_dofs = model.clone();
    if let Path::Fixed { terms } = &mut off_the_dofs.tendons[0].path {
        terms[0].dof = model.nv;
    }
    let mut no_such_tendon = model.clone();
    no_such_tendon.constraints.tendon_limits[0].tendon = 7;
    let mut not_finite = model.clone();
    not_finite.tendons[1].spring_length[0] = f64::NAN;
    for (what, broken) in [("dof", off_the_dofs), ("limit", no_such_tendon), ("spring", not_finite)] {
        let error = broken.validate().expect_err(what).to_string();
        assert!(error.contains("tendon"), "{what}: {error}");
    }
}

#[test]
fn a_vehicle_without_tendons_carries_no_tendon_buffers() {
    let model = Model::compile(&parse_mjcf(&scene("", "")).unwrap().vehicle).unwrap();
    let ws = model.workspace();
    assert!(model.tendons.is_empty() && ws.tendon_moment.is_empty() && ws.tendon_wrench.is_empty());
}

#[test]
fn flags_leave_tendon_terms_out_as_mujocos() {
    let xml = scene(
        r#"<fixed name="t" stiffness="2" damping="1" frictionloss="0.5" range="-1 1">
<joint joint="hinge" coef="1"/></fixed>"#,
        "",
    )
    .replace(
        "<mujoco>",
        r#"<mujoco><option><flag spring="disable" damper="disable" frictionloss="disable" limit="disable"/></option>"#,
    );
    let model = Model::compile(&parse_mjcf(&xml).unwrap().vehicle).unwrap();
    let tendon = &model.tendons[0];
    assert_eq!((tendon.stiffness, tendon.damping), (0.0, 0.0));
    assert!(model.constraints.is_empty());
}

/// (tendons, rest, element, line, words the message must hold)
const REFUSALS: &[(&str, &str, &str, u32, &str)] = &[
    (
        r#"<fixed name="t"><joint joint="elbow" coef="1"/></fixed>"#,
        "",
        "<joint>",
        11,
        "unknown joint 'elbow' in tendon",
    ),
    (r#"<fixed name="t"><joint joint="ball" coef="1"/></fixed>"#, "", "<joint>", 11, "must be slide or hinge"),
    (r#"<fixed name="t"><joint joint="hinge"/></fixed>"#, "", "<joint>", 11, "coef"),
    (
        r#"<fixed name="t"><joint joint="hinge" coef="1"/><joint joint="hinge" coef="2"/></fixed>"#,
        "",
        "<joint>",
        11,
        "repeated",
    ),
    (r#"<fixed name="t"/>"#, "", "<fixed name=\"t\">", 11, "cannot be empty"),
    (r#"<spatial name="t"><site site="s0"/></spatial>"#, "", "<spatial name=\"t\">", 11, "at least two"),
    (r#"<spatial name="t"><site site="s0"/><site site="s9"/></spatial>"#, "", "<site>", 11, "unknown site 's9'"),
    (r#"<spatial name="t"><site site="s0"/><site site="s0"/></spatial>"#, "", "<spatial name=\"t\">", 11, "repeated"),
    (
        r#"<spatial name="t"><site site="s0"/><site site="s1"/><pulley divisor="2"/></spatial>"#,
        "",
        "<spatial name=\"t\">",
        11,
        "end with a pulley",
    ),
    (
        r#"<spatial name="t"><site site="s0"/><pulley divisor="2"/><site site="s1"/></spatial>"#,
        "",
        "<spatial name=\"t\">",
        11,
        "neighbour that is not a pulley",
    ),
    (
        r#"<spatial name="t"><site site="s0"/><geom geom="g" sidesite="s0"/><site site="s1"/></spatial>"#,
        "",
        "<geom>",
        11,
        "sidesite on another body than the geom's",
    ),
    (
        r#"<spatial name="t"><site site="s0"/><geom geom="box"/><site site="s1"/></spatial>"#,
        "",
        "<geom>",
        11,
        "not sphere or cylinder",
    ),
    (
        r#"<spatial name="t"><site site="s0"/><geom geom="h"/><site site="s1"/></spatial>"#,
        "",
        "<geom>",
        11,
        "unknown geom 'h'",
    ),
    (
        r#"<spatial name="t"><site site="s0"/><site site="s1"/><geom geom="g"/></spatial>"#,
        "",
        "<spatial name=\"t\">",
        11,
        "not between two sites",
    ),
    (
        r#"<fixed name="t" armature="-0.1"><joint joint="hinge" coef="1"/></fixed>"#,
        "",
        "<fixed name=\"t\">",
        11,
        "armature cannot be negative",
    ),
    (
        r#"<spatial name="t" armature="0.1"><site site="s0"/><geom geom="g"/><site site="s1"/></spatial>"#,
        "",
        "<spatial name=\"t\">",
        11,
        "geom wrapping not supported by tendon armature",
    ),
    (
        r#"<fixed name="t" actuatorfrcrange="0.5 1"><joint joint="hinge" coef="1"/></fixed>"#,
        "",
        "<fixed name=\"t\">",
        11,
        "invalid actuatorfrcrange",
    ),
    (
        r#"<fixed name="t" actuatorfrclimited="true"><joint joint="hinge" coef="1"/></fixed>"#,
        "",
        "<fixed name=\"t\">",
        11,
        "invalid actuatorfrcrange",
    ),
    (
        r#"<fixed name="t" stiffness="1 2"><joint joint="hinge" coef="1"/></fixed>"#,
        "",
        "<fixed name=\"t\">",
        11,
        "nonlinear stiffness",
    ),
    (
        r#"<fixed name="t" springlength="0.3 0.1"><joint joint="hinge" coef="1"/></fixed>"#,
        "",
        "<fixed name=\"t\">",
        11,
        "invalid springlength",
    ),
    (
        r#"<fixed name="t" limited="true"><joint joint="hinge" coef="1"/></fixed>"#,
        "",
        "<fixed name=\"t\">",
        11,
        "invalid limits",
    ),
    (
        r#"<fixed name="t"><joint joint="hinge" coef="1"/></fixed>"#,
        r#"<actuator><position tendon="t" kp="1" inheritrange="1"/></actuator>"#,
        "<position>",
        13,
        "no range",
    ),
    (
        r#"<fixed name="t"><joint joint="hinge" coef="1"/></fixed>"#,
        r#"<sensor><tendonlimitfrc tendon="t"/></sensor>"#,
        "<tendonlimitfrc>",
        13,
        "tendon must be limited",
    ),
    (
        r#"<fixed name="t"><joint joint="hinge" coef="1"/></fixed>"#,
        r#"<equality><tendon tendon1="t" tendon2="t"/></equality>"#,
        "<tendon>",
        13,
        "same tendon",
    ),
    (
        r#"<fixed name="t"><joint joint="hinge" coef="1"/></fixed>"#,
        r#"<sensor><tendonpos tendon="u"/></sensor>"#,
        "<tendonpos>",
        13,
        "unknown tendon 'u'",
    ),
];

#[test]
fn bad_tendons_are_refused_with_element_line_and_reason() {
    for &(tendons, rest, element, line, words) in REFUSALS {
        let error = refused(tendons, rest);
        let message = error.to_string();
        assert!(
            message.contains(element) && message.contains(&format!("line {line}")) && message.contains(words),
            "{tendons} {rest}: {message}"
        );
    }
    let twice = refused(
        r#"<fixed name="t"><joint joint="hinge" coef="1"/></fixed>
<fixed name="t"><joint joint="slide" coef="1"/></fixed>"#,
        "",
    );
    assert!(matches!(twice, MjcfError::DuplicateName { line: 12, .. }), "{twice}");
}

/// Whether dof `a` is dof `b`, or one is the other's ancestor in MuJoCo's dof tree.
fn on_one_chain(model: &Model, a: usize, b: usize) -> bool {
    let link_of = |d: usize| model.links.iter().position(|l| (l.dof_adr..l.dof_adr + l.ndof).contains(&d)).unwrap();
    let above = |lower: usize, upper: usize| {
        let (low, up) = (link_of(lower), link_of(upper));
        if low == up {
            return upper <= lower;
        }
        let mut parent = model.links[low].parent;
        while let Some(p) = parent {
            if p == up {
                return true;
            }
            parent = model.links[p].parent;
        }
        false
    };
    above(a, b) || above(b, a)
}

#[test]
fn armature_terms_sum_to_mujocos_tree_sparse_share_of_a_jt_j() {
    let imported = load_mjcf(&fixture("tendon_armature.xml")).unwrap();
    let model = Model::compile(&imported.vehicle).unwrap();
    let nv = model.nv;
    // One term on the chain, two leaves across the arms (no common dof),
    // and two leaves and their fork (the bus's last dof) for the sling.
    let count = |k: usize| model.tendon_inertia.iter().filter(|t| t.tendon == k).count();
    assert_eq!([count(0), count(1), count(2), count(3)], [1, 2, 3, 0]);
    let mut ws = model.workspace();
    for step in 0..5 {
        let theta: Vec<f64> =
            model.qpos0.iter().enumerate().map(|(k, q)| q + 0.3 * ((k * 7 + step * 3) as f64).sin()).collect();
        ws.set_configuration(&model, &theta).unwrap();
        for (k, tendon) in model.tendons.iter().enumerate() {
            let arms = ws.tendon_moment_row(&model, k).to_vec();
            let mut sum = vec![0.0; nv * nv];
            for term in model.tendon_inertia.iter().filter(|t| t.tendon == k) {
                let kept: Vec<f64> = (0..nv)
                    .map(|d| if on_one_chain(&model, d, term.dof) && d <= term.dof { arms[d] } else { 0.0 })
                    .collect();
                for i in 0..nv {
                    for j in 0..nv {
                        sum[i * nv + j] += term.weight * kept[i] * kept[j];
                    }
                }
            }
            for i in 0..nv {
                for j in 0..nv {
                    let masked = if on_one_chain(&model, i, j) { tendon.armature * arms[i] * arms[j] } else { 0.0 };
                    assert!(
                        (sum[i * nv + j] - masked).abs() < 1e-14,
                        "tendon {k}, ({i}, {j}): {} vs {masked}",
                        sum[i * nv + j]
                    );
                }
            }
        }
    }
}

#[test]
fn armature_compiles_to_mujocos_qpos0_data() {
    let imported = load_mjcf(&fixture("tendon_armature.xml")).unwrap();
    let model = Model::compile(&imported.vehicle).unwrap();
    // MuJoCo 4.0's tendon_invweight0, dof_invweight0 and the servo's kv from
    // dampratio for this file (its Python bindings): all from M with the
    // tendons' armature (without it they are far off: kv 9.51).
    let tendon = [7.812835940626739, 8.0813756031482, 0.1395629824230771, 60.694970737099204];
    let dof = [
        0.015829077160967552,
        0.015829077160967552,
        0.015829077160967552,
        0.1786949239242169,
        0.1786949239242169,
        0.1786949239242169,
        2.671319098371625,
        4.07682515385095,
        60.694970737099204,
        23.685102542372977,
        23.685102542372977,
        23.685102542372977,
        0.2503399872806316,
    ];
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-12 * b.abs().max(1.0);
    for (t, expected) in model.tendons.iter().zip(tendon) {
        assert!(close(t.invweight0, expected), "{} vs {expected}", t.invweight0);
    }
    for (found, expected) in model.constraints.dof_invweight0.iter().zip(dof) {
        assert!(close(*found, expected), "{found} vs {expected}");
    }
    assert!(close(model.actuators[0].bias[2], -16.75937862944914), "{}", model.actuators[0].bias[2]);
}

#[test]
fn a_world_geom_a_tendon_wraps_around_is_reported_used_not_ignored() {
    let xml = r#"<mujoco>
<worldbody>
<geom name="post" type="cylinder" size="0.05 0.2" pos="0.3 0 0"/>
<geom name="pad" type="sphere" size="0.05" pos="0.3 0.2 0" contype="0" conaffinity="0"/>
<geom name="floor" type="plane" size="1 1 0.1"/>
<site name="anchor" pos="0.3 -0.2 0"/>
<body name="arm"><joint name="hinge" axis="0 0 1"/><geom size="0.1"/><site name="tip" pos="0.6 0 0"/></body>
</worldbody>
<tendon>
<spatial name="cord"><site site="anchor"/><geom geom="post"/><site site="tip"/></spatial>
<spatial name="strap"><site site="anchor"/><geom geom="pad"/><site site="tip"/></spatial>
</tendon>
</mujoco>"#;
    let warnings = parse_mjcf(xml).unwrap().warnings;
    let at = |line: u32| warnings.iter().filter(|w| w.line == line).map(|w| w.message.as_str()).collect::<Vec<_>>();
    // The obstacle that collides: used, only its contacts left out.
    let post = at(3);
    assert_eq!(post.len(), 1, "{warnings:?}");
    assert!(post[0].starts_with("used as the wrap obstacle of <spatial name=\"cord\">"), "{}", post[0]);
    assert!(!post[0].contains("ignored"), "{}", post[0]);
    // The obstacle without contacts: nothing of it is left out.
    assert!(at(4).is_empty(), "{warnings:?}");
    // A world geom nothing uses is still ignored.
    assert!(at(5).iter().any(|m| m.starts_with("ignored")), "{warnings:?}");
}

#[test]
fn a_side_site_on_the_geoms_body_outside_it_is_taken_one_inside_refused() {
    let scene = |side: &str| {
        format!(
            r#"<mujoco><worldbody><body name="base"><freejoint/><geom size="0.2"/><site name="s0" pos="0.1 0 0"/>
<body name="arm" pos="0.5 0 0"><joint axis="0 1 0"/><geom size="0.1"/>
<geom name="drum" type="cylinder" size="0.05 0.1" pos="0.2 0 0" euler="90 0 0"/>
<site name="s1" pos="0.4 0 0"/><site name="side" pos="{side}"/></body></body></worldbody>
<tendon><spatial><site site="s0"/><geom geom="drum" sidesite="side"/><site site="s1"/></spatial></tendon></mujoco>"#
        )
    };
    let vehicle = parse_mjcf(&scene("0.2 0 -0.1")).unwrap().vehicle;
    let nudyn::vehicle::TendonPath::Spatial(points) = &vehicle.tendons[0].path else { panic!("a spatial tendon") };
    assert!(matches!(points[1], nudyn::vehicle::PathPoint::Geom(geom) if geom.side == Some(2)), "{points:?}");
    let model = Model::compile(&vehicle).unwrap();
    let described = serde_json::to_value(nudyn::describe::Description::of(&vehicle, &model)).unwrap();
    assert_eq!(described["tendons"][0]["path"][1]["sidesite"], "side");
    // Inside the cylinder's radius (its axis is y here), however far along the axis.
    let message = parse_mjcf(&scene("0.21 0.5 0.02")).unwrap_err().to_string();
    assert!(message.contains("sidesite inside the geom"), "{message}");
    assert!(message.contains("pass through the geom"), "{message}");
}
