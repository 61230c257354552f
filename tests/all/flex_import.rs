//! An MJCF body made flexible by `<custom><text name="nudyn:modal:BODY"
//! data="FILE"/>` (docs/flexible.md): the file found beside the MJCF, read,
//! checked and held to the body's inertial at import; its modes appended
//! to θ and ν at compile, what does not take them in yet refused; a body
//! with no modes the rigid body exactly. Fixture: tests/fixtures/flex/bench_vehicle.xml.

use std::path::{Path, PathBuf};

use nudyn::mjcf::load_mjcf;
use nudyn::model::{Model, ModelError};

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/flex")
}

/// The fixture vehicle (its text changed by `edit`) and the modal file
/// (`modal`) in a temporary folder of their own, removed when this is
/// dropped; it derefs to the vehicle's path.
struct Variant {
    _folder: tempfile::TempDir,
    vehicle: PathBuf,
}

impl std::ops::Deref for Variant {
    type Target = Path;

    fn deref(&self) -> &Path {
        &self.vehicle
    }
}

fn variant(name: &str, edit: impl Fn(String) -> String, modal: impl Fn(String) -> String) -> Variant {
    let folder = tempfile::Builder::new().prefix(&format!("nudyn-flex-import-{name}-")).tempdir().unwrap();
    let xml = std::fs::read_to_string(fixtures().join("bench_vehicle.xml")).unwrap();
    std::fs::write(folder.path().join("bench_vehicle.xml"), edit(xml)).unwrap();
    let json = std::fs::read_to_string(fixtures().join("bench.json")).unwrap();
    std::fs::write(folder.path().join("bench.json"), modal(json)).unwrap();
    let vehicle = folder.path().join("bench_vehicle.xml");
    Variant { _folder: folder, vehicle }
}

fn import_error(path: &Path) -> String {
    load_mjcf(path).unwrap_err().to_string()
}

#[test]
fn the_modal_file_is_read_beside_the_mjcf_and_its_modes_follow_the_rigid_coordinates() {
    let imported = load_mjcf(&fixtures().join("bench_vehicle.xml")).unwrap();
    assert!(imported.warnings.is_empty(), "{:?}", imported.warnings);
    let [bench] = imported.vehicle.flexible.as_slice() else { panic!("{:?}", imported.vehicle.flexible) };
    assert_eq!((bench.body.as_str(), bench.nodes.len(), bench.modes.len()), ("bench", 3, 3));
    let model = Model::compile(&imported.vehicle).unwrap();
    // Free joint (7, 6) and hinge (1, 1), then the bench's three modes.
    assert_eq!((model.nq, model.nv), (11, 10));
    let [flexible] = model.flexible.as_slice() else { panic!() };
    assert_eq!((flexible.qpos_adr, flexible.dof_adr, flexible.link), (8, 7, 2));
    assert_eq!(model.qpos0[8..], [0.0; 3]);
    // The bench's mass is its nodes', not its link's.
    assert_eq!(model.links[2].mass, 0.0);
}

#[test]
fn a_flexible_body_welded_to_the_world_or_with_tendons_is_refused_at_compile() {
    let welded = variant(
        "welded",
        |xml| {
            let other = "<body name=\"other\"><joint type=\"slide\"/><inertial pos=\"0 0 0\" mass=\"1\" diaginertia=\"1 1 1\"/></body>";
            xml.replace("<joint name=\"drive\" type=\"hinge\" axis=\"0 0 1\"/>", "")
                .replace("<freejoint/>", "")
                .replace("</worldbody>", &format!("{other}</worldbody>"))
        },
        |j| j,
    );
    let error = Model::compile(&load_mjcf(&welded).unwrap().vehicle).unwrap_err();
    assert_eq!(error, ModelError::FlexibleOnWorld { body: "bench".into() });
    let tendon = variant(
        "tendon",
        |xml| {
            xml.replace(
                "</worldbody>",
                "</worldbody><tendon><fixed name=\"t\"><joint joint=\"drive\" coef=\"1\"/></fixed></tendon>",
            )
        },
        |j| j,
    );
    let error = Model::compile(&load_mjcf(&tendon).unwrap().vehicle).unwrap_err();
    assert_eq!(error, ModelError::FlexibleWith { body: "bench".into(), feature: "tendons" });
    assert!(error.to_string().contains("tendons do not take modal degrees of freedom in yet"), "{error}");
}

/// A child with a joint at a node that the modes move rides that node
/// (docs/flexible.md, "Child bodies at nodes"); one welded there joins the
/// node's inertia ("Bodies welded at nodes"). A child elsewhere, or
/// at a node no mode moves (bench.json's "root"), is fixed to the bench's
/// frame, as documented; with no modes a child at the tip is the rigid
/// vehicle's.
#[test]
fn a_child_body_at_a_node_rides_it_and_a_welded_one_joins_its_inertia() {
    let child = |pos: &str, joint: &str| {
        format!(
            "<body name=\"panel\" pos=\"{pos}\">{joint}\
             <inertial pos=\"0.2 0 0\" mass=\"1\" diaginertia=\"0.1 0.1 0.1\"/></body></body></body>"
        )
    };
    let hinge = "<joint name=\"yoke\" axis=\"0 1 0\"/>";
    let at_tip = |xml: String| xml.replacen("</body>\n    </body>", &child("1 0 0.0000005", hinge), 1);
    let model = Model::compile(&load_mjcf(&variant("child_at_node", at_tip, |j| j)).unwrap().vehicle).unwrap();
    let yoke = model.links.iter().position(|l| l.joint_name == "yoke").unwrap();
    let flexible = &model.flexible[0];
    assert_eq!(flexible.node_children.len(), 1);
    assert_eq!(flexible.node_children[0].link, yoke);
    assert_eq!(flexible.modal.nodes[flexible.rotating[flexible.node_children[0].slot]].name, "tip");
    // Welded there, its mass joins the node (1 kg at 0.2 m from it), not the bench's link.
    let welded_at_tip = |xml: String| xml.replacen("</body>\n    </body>", &child("1 0 0.0000005", ""), 1);
    let model = Model::compile(&load_mjcf(&variant("welded_at_node", welded_at_tip, |j| j)).unwrap().vehicle).unwrap();
    let flexible = &model.flexible[0];
    assert!(flexible.node_children.is_empty());
    let slot = flexible.rotating.iter().position(|&j| flexible.modal.nodes[j].name == "tip").unwrap();
    let welded = flexible.welded[slot];
    let first_moment = welded.fixed_view::<3, 3>(0, 3).norm() / 2f64.sqrt();
    assert!((welded[(3, 3)] - 1.0).abs() < 1e-12 && (first_moment - 0.2).abs() < 1e-6, "{welded}");
    // fusestatic keeps it a body (fused into the bench, it would change the bench's inertial).
    let fused = |xml: String| welded_at_tip(xml).replace("<custom>", "<compiler fusestatic=\"true\"/><custom>");
    let model = Model::compile(&load_mjcf(&variant("welded_fusestatic", fused, |j| j)).unwrap().vehicle).unwrap();
    assert_eq!(model.flexible[0].welded[slot], welded);
    // A flexible body welded there is refused, naming both bodies and the node.
    let flexible_at_tip = |xml: String| {
        let second = "<body name=\"bench2\" pos=\"1 0 0\">\
                      <inertial pos=\"0.375 0 0\" mass=\"4\" diaginertia=\"0.01 0.7075 0.7075\"/></body></body></body>";
        xml.replacen("</body>\n    </body>", second, 1).replace(
            "<text name=\"nudyn:modal:bench\" data=\"bench.json\"/>",
            "<text name=\"nudyn:modal:bench\" data=\"bench.json\"/><text name=\"nudyn:modal:bench2\" data=\"bench.json\"/>",
        )
    };
    let vehicle = load_mjcf(&variant("flexible_at_node", flexible_at_tip, |j| j)).unwrap().vehicle;
    let error = Model::compile(&vehicle).unwrap_err();
    let expected =
        ModelError::FlexibleWeldedAtNode { body: "bench2".into(), carrier: "bench".into(), node: "tip".into() };
    assert_eq!(error, expected);
    assert!(error.to_string().contains("give it one"), "{error}");
    let bench = &model.links[flexible.link];
    let rigid = Model::compile(&load_mjcf(&variant("plain_bench", |xml| xml, |j| j)).unwrap().vehicle).unwrap();
    assert_eq!(bench.mass, rigid.links[rigid.flexible[0].link].mass);
    for (name, pos) in [("child_beside_node", "1 0 0.00001"), ("child_at_clamped_node", "0 0 0")] {
        let elsewhere = |xml: String| xml.replacen("</body>\n    </body>", &child(pos, hinge), 1);
        let model = Model::compile(&load_mjcf(&variant(name, elsewhere, |j| j)).unwrap().vehicle).unwrap();
        assert!(model.flexible[0].node_children.is_empty(), "{name}");
    }
    Model::compile(&load_mjcf(&variant("child_at_rigid_node", at_tip, no_modes)).unwrap().vehicle).unwrap();
}

/// The modal file `json` with its modes taken out.
fn no_modes(json: String) -> String {
    let start = json.find("\"modes\": [").unwrap();
    format!("{}\"modes\": []\n}}\n", &json[..start])
}

#[test]
fn with_no_modes_the_flexible_body_is_the_rigid_body() {
    let flexible = variant("rigid", |xml| xml, no_modes);
    let imported = load_mjcf(&flexible).unwrap();
    assert!(imported.vehicle.flexible[0].modes.is_empty());
    let without_text =
        variant("plain", |xml| xml.replace("<text name=\"nudyn:modal:bench\" data=\"bench.json\"/>", ""), |j| j);
    let rigid = load_mjcf(&without_text).unwrap();
    assert!(rigid.vehicle.flexible.is_empty());
    // An empty <custom> is ignored with a warning, as before; the models are the same.
    assert_eq!(rigid.warnings.len(), 1, "{:?}", rigid.warnings);
    assert_eq!(Model::compile(&imported.vehicle).unwrap(), Model::compile(&rigid.vehicle).unwrap());
}

#[test]
fn a_bad_hook_or_file_is_an_error_naming_the_text_element() {
    let text = "line 9: <text name=\"nudyn:modal:";
    // (case, in the MJCF: from → to, in the modal file: from → to, expected)
    let cases = [
        (
            "nobody",
            ("nudyn:modal:bench", "nudyn:modal:panel"),
            ("", ""),
            "there is no body named 'panel' to make flexible",
        ),
        ("nofile", ("data=\"bench.json\"", "data=\"panel.json\""), ("", ""), "cannot read the modal file"),
        ("nodata", (" data=\"bench.json\"", ""), ("", ""), "data"),
        ("heavier", ("mass=\"4\"", "mass=\"4.1\""), ("", ""), "body 'bench': its modal file's nodes give mass 4 kg"),
        (
            "badfile",
            ("", ""),
            ("\"damping_ratio\": 0.01", "\"damping_ratio\": -0.01"),
            "modes[1].damping_ratio is -0.01",
        ),
    ];
    for (name, (xml_from, xml_to), (json_from, json_to), expected) in cases {
        let replace = |text: String, from: &str, to: &str| if from.is_empty() { text } else { text.replace(from, to) };
        let error = import_error(&variant(name, |x| replace(x, xml_from, xml_to), |j| replace(j, json_from, json_to)));
        assert!(error.contains(expected), "{name}: {error}");
        if name != "nodata" {
            assert!(error.contains(text), "{name}: {error}");
        }
    }
}

#[test]
fn a_flexible_body_is_not_fused_into_its_parent() {
    // Without a joint, fusestatic would merge the bench into the bus, and its nodes with it.
    let fused = variant(
        "fused",
        |x| {
            x.replace("<joint name=\"drive\" type=\"hinge\" axis=\"0 0 1\"/>", "")
                .replace("<option", "<compiler fusestatic=\"true\"/>\n  <option")
        },
        |j| j,
    );
    let imported = load_mjcf(&fused).unwrap();
    assert!(imported.vehicle.bodies.iter().any(|b| b.name == "bench"));
}
