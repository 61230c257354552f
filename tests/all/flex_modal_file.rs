//! Flexible bodies' modal data files (src/flex): what a valid file gives,
//! and the error each kind of bad file gets. The fixture
//! tests/fixtures/flex/bench.json is small enough to check by hand: three
//! nodes on the x axis (2, 1 and 1 kg at 0, 0.5 and 1 m) and three modes,
//! each moving one node, with unit modal masses.

use std::path::Path;

use nudyn::flex::{ModalBody, ModalError, modal_file};
use nudyn::math::{Mat3, Vec3};
use nudyn::vehicle::MassProperties;

fn fixture() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/fixtures/flex/bench.json"))
}

fn bench() -> ModalBody {
    modal_file::read(fixture(), "bench").unwrap()
}

fn bench_text() -> String {
    std::fs::read_to_string(fixture()).unwrap()
}

/// The fixture's text with `from` replaced by `to` (once, and it must be there).
fn edited(from: &str, to: &str) -> String {
    let text = bench_text();
    assert_eq!(text.matches(from).count(), 1, "{from:?} must occur once in the fixture");
    text.replacen(from, to, 1)
}

fn error_of(text: &str) -> String {
    modal_file::parse(text, "bench").unwrap_err()
}

/// The body's `<inertial>` that the fixture's nodes reproduce, worked out by
/// hand: centre of mass at x = (0.5 + 1)/4, Iyy = Izz = Σ m d² + 0.02.
fn inertial() -> MassProperties {
    let i_bending = 2.0 * 0.375f64.powi(2) + 0.125f64.powi(2) + 0.625f64.powi(2) + 0.02;
    MassProperties {
        mass: 4.0,
        com: Vec3::new(0.375, 0.0, 0.0),
        inertia: Mat3::from_diagonal(&Vec3::new(0.01, i_bending, i_bending)),
    }
}

#[test]
fn a_valid_file_gives_si_units_and_unit_modal_masses() {
    let body = bench();
    assert_eq!(body.nodes.iter().map(|n| n.name.as_str()).collect::<Vec<_>>(), ["root", "middle", "tip"]);
    assert_eq!(body.modes.len(), 3);
    let tau = std::f64::consts::TAU;
    for (mode, (hz, zeta)) in body.modes.iter().zip([(1.5, 0.005), (4.0, 0.01), (9.0, 0.02)]) {
        assert!((mode.angular_frequency - tau * hz).abs() < 1e-12);
        assert_eq!(mode.damping_ratio, zeta);
    }
    // Each mode moves one node: its own modal mass, by hand.
    assert_eq!(body.modes[0].translation[1], Vec3::new(0.0, 0.0, 1.0));
    assert_eq!(body.modes[1].rotation[1], Vec3::new(10.0, 0.0, 0.0));
    assert_eq!(body.modes[2].rotation[2], Vec3::new(0.0, 0.3, 0.0));
    body.check_mass_properties(Some(&inertial())).unwrap();
}

#[test]
fn other_units_give_the_same_body() {
    // mm and g: positions ×1000, masses ×1000, rotary inertias ×1e9; shapes
    // mass-normalized in those units: translations ×1000/√(1000·1e6), rotations ×1/√1e9.
    let mut file: serde_json::Value = serde_json::from_str(&bench_text()).unwrap();
    file["units"] = serde_json::json!({ "length": "mm", "mass": "g", "frequency": "rad/s" });
    let scale_translation = 1e3 / (1e3f64 * 1e6).sqrt();
    let scale_rotation = 1.0 / (1e3f64 * 1e6).sqrt();
    for node in file["nodes"].as_array_mut().unwrap() {
        for x in node["position"].as_array_mut().unwrap() {
            *x = (x.as_f64().unwrap() * 1e3).into();
        }
        node["mass"] = (node["mass"].as_f64().unwrap() * 1e3).into();
        if let Some(inertia) = node.get_mut("rotary_inertia") {
            for x in inertia.as_array_mut().unwrap() {
                *x = (x.as_f64().unwrap() * 1e9).into();
            }
        }
    }
    for mode in file["modes"].as_array_mut().unwrap() {
        mode["frequency"] = (mode["frequency"].as_f64().unwrap() * std::f64::consts::TAU).into();
        for node in mode["shape"].as_array_mut().unwrap() {
            for (k, x) in node.as_array_mut().unwrap().iter_mut().enumerate() {
                let scale = if k < 3 { scale_translation } else { scale_rotation };
                *x = (x.as_f64().unwrap() * scale).into();
            }
        }
    }
    let converted = modal_file::parse(&file.to_string(), "bench").unwrap();
    let si = bench();
    for (a, b) in converted.nodes.iter().zip(&si.nodes) {
        assert!((a.position - b.position).norm() < 1e-15 && (a.mass - b.mass).abs() < 1e-15);
        assert!((a.rotary_inertia - b.rotary_inertia).norm() < 1e-15);
    }
    for (a, b) in converted.modes.iter().zip(&si.modes) {
        assert!((a.angular_frequency - b.angular_frequency).abs() < 1e-12);
        for j in 0..3 {
            assert!((a.translation[j] - b.translation[j]).norm() < 1e-12, "{a:?} {b:?}");
            assert!((a.rotation[j] - b.rotation[j]).norm() < 1e-12, "{a:?} {b:?}");
        }
    }
}

#[test]
fn modes_not_mass_normalized_are_scaled_to_unit_modal_mass() {
    // The first mode at twice its size: modal mass 4, so it is halved.
    let text = edited("[0, 0, 1, 0, 0, 0]", "[0, 0, 2, 0, 0, 0]")
        .replace("\"mass_normalized\": true", "\"mass_normalized\": false");
    let body = modal_file::parse(&text, "bench").unwrap();
    assert_eq!(body.modes[0].translation[1], Vec3::new(0.0, 0.0, 1.0));
    // Said to be normalized, the same file is refused.
    let refused = error_of(&edited("[0, 0, 1, 0, 0, 0]", "[0, 0, 2, 0, 0, 0]"));
    assert!(refused.contains("modes[0]'s modal mass is 4"), "{refused}");
}

#[test]
fn bad_files_get_an_error_naming_the_field() {
    let cases = [
        (
            edited("\"tip\", \"position\"", "\"middle\", \"position\""),
            "nodes[2] (\"middle\"): the name is used by an earlier node",
        ),
        (edited("\"mass\": 2.0", "\"mass\": -2.0"), "nodes[0] (\"root\").mass is -2"),
        (
            edited("[0.01, 0.02, 0.02, 0.0, 0.0, 0.0]", "[0.01, 0.02, 0.02, 0.5, 0.0, 0.0]"),
            "rotary_inertia has principal moments",
        ),
        (edited("\"frequency\": 4.0", "\"frequency\": 0.0"), "modes[1].frequency is 0"),
        (edited("\"frequency\": 4.0", "\"frequency\": 1.0"), "modes[1] has a lower frequency than modes[0]"),
        (edited("\"damping_ratio\": 0.02", "\"damping_ratio\": -0.02"), "modes[2].damping_ratio is -0.02"),
        (
            edited(
                "[0, 0, 1, 0, 0, 0], [0, 0, 0, 0, 0, 0]]",
                "[0, 0, 1, 0, 0, 0], [0, 0, 0, 0, 0, 0], [0, 0, 0, 0, 0, 0]]",
            ),
            "modes[0].shape has 4 entries; expected one per node (3)",
        ),
        (edited("[0, 1, 0, 0, 0.3, 0]", "[0, 1, 0, 0, 0.3, 0]], \"extra\": [0"), "unknown field `extra`"),
        // The third mode also moves the middle node along z, as the first does.
        (
            edited(
                "[0, 0, 0, 0, 0, 0], [0, 0, 0, 0, 0, 0], [0, 1, 0, 0, 0.3, 0]",
                "[0, 0, 0, 0, 0, 0], [0, 0, 0.1, 0, 0, 0], [0, 1, 0, 0, 0.3, 0]",
            ),
            "modes[0] and modes[2] are not orthogonal",
        ),
        (edited("\"version\": 1", "\"version\": 2"), "version 2 is not one this nudyn reads"),
        (edited("\"length\": \"m\"", "\"length\": \"in\""), "units.length is \"in\""),
        (edited("\"damping_ratio\": 0.005", "\"damping_ratio\": NaN"), "expected value at line 13 column 42"),
        (bench_text().replace("\"modes\": [", "\"no_modes\": ["), "unknown field `no_modes`"),
    ];
    for (text, expected) in cases {
        let error = error_of(&text);
        assert!(error.contains(expected), "expected {expected:?} in {error:?}");
    }
    let text = bench_text();
    let without_modes = format!("{}}}", &text[..text.find(",\n  \"modes\"").unwrap()]);
    let missing_modes = error_of(&without_modes);
    assert!(missing_modes.contains("missing field `modes`"), "{missing_modes}");
}

#[test]
fn errors_name_the_body_and_the_file() {
    let missing = modal_file::read(Path::new("/nonexistent/panel.json"), "array_left").unwrap_err();
    assert!(matches!(missing, ModalError::Read { .. }));
    assert!(
        missing.to_string().starts_with("cannot read the modal file /nonexistent/panel.json of body 'array_left'"),
        "{missing}"
    );
}

#[test]
fn the_nodes_must_reproduce_the_bodys_inertial() {
    let body = bench();
    let mut heavier = inertial();
    heavier.mass *= 1.0 + 1e-5;
    let error = body.check_mass_properties(Some(&heavier)).unwrap_err().to_string();
    assert!(error.starts_with("body 'bench': its modal file's nodes give mass 4 kg"), "{error}");
    assert!(error.contains("but its inertial gives mass 4.00004 kg") && error.contains("mass differs by"), "{error}");
    let mut shifted = inertial();
    shifted.com.y = 1e-3;
    let error = body.check_mass_properties(Some(&shifted)).unwrap_err().to_string();
    assert!(error.contains("centre of mass differs"), "{error}");
    let mut turned = inertial();
    turned.inertia[(0, 1)] = 1e-4;
    turned.inertia[(1, 0)] = 1e-4;
    let error = body.check_mass_properties(Some(&turned)).unwrap_err().to_string();
    assert!(error.contains("inertia differs"), "{error}");
    // Within the tolerance it passes; a massless body cannot carry the nodes.
    let mut close = inertial();
    close.mass *= 1.0 + 1e-8;
    body.check_mass_properties(Some(&close)).unwrap();
    assert!(body.check_mass_properties(None).is_err());
}
